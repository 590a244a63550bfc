//! The corpus of **recorded** human driving: interactions mined from imported recordings, each
//! with its two vehicles' states, controls (inverse kinematics) and routes (the lane network), and
//! where the data came from and under which licence.
//!
//! **Import** ([`import_scenario`]): a recording's tracks are mined ([`crate::mining`]); for every
//! interaction between two vehicles, each vehicle's track (the piece without gaps around the
//! conflict) is smoothed and inverted into states and controls ([`crate::inverse`]) and given its
//! route on the recording's lane network ([`LaneletNetwork::route_of`]; a recording without lanes,
//! such as a CSV file, gives each vehicle its own smoothed path as route, and says so in
//! [`RecordedAgent::route_from`]: such a route tells the model more than a lane would). An interaction whose
//! vehicle has no route (outside every lanelet) or whose inversion fails is counted, not kept.
//! Every episode keeps its recording, source file, dataset and licence tag.
//!
//! **On disk**: JSON lines. The first line is a [`RecordedHeader`] (`"format":
//! "v2t-recorded-corpus"`, version, `"synthetic": false`, the source files with their track
//! counts); every following line is one [`RecordedEpisode`]. Reading checks the format, the
//! version and the count and names the line of any error. Writing goes to a temporary file that is
//! renamed into place, so an error never leaves half a corpus.

use serde::{Deserialize, Serialize};
use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, State};
use v2t_model::metrics::Dimensions;

use crate::inverse::{InverseOptions, split_at_gaps, to_controls};
use crate::lanes::LaneletNetwork;
use crate::mining::{InteractionKind, MiningOptions, mine};
use crate::stats::Histogram;
use crate::tracks::{AgentKind, Episode, Track};

/// Format name in the header.
pub const FORMAT: &str = "v2t-recorded-corpus";
/// Format version written and read.
pub const VERSION: u32 = 1;
/// Route points are kept this far apart, m.
const ROUTE_SPACING_M: f64 = 2.0;

/// One imported file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceFile {
    /// The file as given to the importer.
    pub file: String,
    /// Its recording (scenario) id.
    pub recording: String,
    /// The dataset it holds (e.g. `NGSIM US-101`).
    pub dataset: String,
    /// Licence tag of the data (e.g. `NGSIM: US DOT public data; CommonRoad conversion BSD-3-Clause`).
    pub licence: String,
    /// The file format (e.g. `CommonRoad 2018b`).
    pub format: String,
    /// Sampling period of the recording, s (the episodes' may be finer: `--resample`).
    pub dt_s: f64,
    /// Tracks in the file (every road user).
    pub tracks: usize,
    /// … of which motor vehicles.
    pub vehicles: usize,
    /// Interactions mined.
    pub mined: usize,
    /// … of which kept as episodes.
    pub kept: usize,
    /// … dropped because a vehicle is on no lanelet.
    pub no_route: usize,
    /// … dropped because inverse kinematics failed (too short a piece, a hole at the conflict).
    pub no_controls: usize,
    /// … dropped because the lanes show no interaction ([`on_lanes`]): two vehicles side by side
    /// in their own lanes whose driven corridors touch, or a vehicle leaving the other's lane.
    pub not_interaction: usize,
    /// Motor-vehicle tracks of vehicles an earlier file of the same import already held (the
    /// importer's `--dedup`, [`crate::dedup`]; 0 without it).
    #[serde(default)]
    pub duplicate_vehicles: usize,
    /// Kept interactions dropped because an earlier file already gave the same two vehicles'
    /// (`--dedup`; not counted in `kept`).
    #[serde(default)]
    pub duplicate_episodes: usize,
    /// Motor vehicles that turn left by at least [`LEFT_TURN_VEHICLE_RAD`] over their track, with
    /// or without another vehicle to interact with (with `--dedup`, each vehicle once: counted in
    /// the first file where it turns).
    #[serde(default)]
    pub left_turning_vehicles: usize,
}

/// A vehicle whose heading turns left by at least this over its track counts as turning left, rad
/// (60°).
pub const LEFT_TURN_VEHICLE_RAD: f64 = std::f64::consts::FRAC_PI_3;

/// Whether `track` is a motor vehicle that turns left by at least [`LEFT_TURN_VEHICLE_RAD`].
pub fn turns_left(track: &Track) -> bool {
    track.kind.is_vehicle() && track.heading_change_rad().is_some_and(|d| d >= LEFT_TURN_VEHICLE_RAD)
}

/// The motion of a vehicle turning left, as an episode's vehicle is kept: the gap-free piece of
/// `track` that turns left most (at least [`LEFT_TURN_VEHICLE_RAD`]), smoothed and inverted
/// ([`to_controls`]). `None` when no piece turns left that far or the inversion fails.
pub fn left_turn_states(track: &Track, options: &InverseOptions) -> Option<Vec<State>> {
    if !track.kind.is_vehicle() {
        return None;
    }
    let piece = split_at_gaps(track)
        .into_iter()
        .filter_map(|p| p.heading_change_rad().map(|d| (d, p)))
        .filter(|(d, _)| *d >= LEFT_TURN_VEHICLE_RAD)
        .max_by(|a, b| a.0.total_cmp(&b.0))?
        .1;
    to_controls(&piece, options).ok().map(|r| r.trajectory.states)
}

/// One vehicle of a recorded episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedAgent {
    /// Track id in the recording.
    pub id: String,
    /// Kind of road user.
    pub kind: AgentKind,
    /// Footprint, when recorded.
    pub dims: Option<Dimensions>,
    /// Recording time of `states[0]`, s.
    pub start_s: f64,
    /// Smoothed states at `start_s + k · dt`, one more than controls.
    pub states: Vec<State>,
    /// Controls whose rollout gives the states.
    pub controls: Vec<Control>,
    /// Its route: the centreline of the lane it ends in ([`LaneletNetwork::route_of`]), or, for a
    /// recording without lanes (CSV), its own smoothed path; points about 2 m apart.
    pub route: Vec<Point2>,
    /// Where the route came from: `lanes` or `driven path`.
    pub route_from: String,
    /// RMS distance between recorded and smoothed positions, m.
    pub smoothing_rms_m: f64,
    /// The vehicle's number across the files of one `corpus import --dedup` (CommonRoad's cuts of
    /// one recording renumber a vehicle; this number does not change); absent without `--dedup`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle: Option<usize>,
}

/// One mined interaction with its two vehicles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedEpisode {
    /// `<recording>/<actor>-<other>@<conflict time>`.
    pub id: String,
    /// Recording id (the held-out split is by recording).
    pub recording: String,
    /// The file it was imported from, as given to the importer.
    pub file: String,
    /// Dataset.
    pub dataset: String,
    /// Licence tag of the data.
    pub licence: String,
    /// Sampling period, s.
    pub dt_s: f64,
    /// The interaction (recording time).
    pub mined: crate::mining::Interaction,
    /// The actor first, then the other vehicle.
    pub agents: Vec<RecordedAgent>,
}

impl RecordedEpisode {
    /// The measured PET, s.
    pub fn pet_s(&self) -> f64 {
        self.mined.pet_s
    }
}

/// A recorded corpus.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RecordedCorpus {
    /// The files imported, in order.
    pub sources: Vec<SourceFile>,
    /// The episodes, file by file.
    pub episodes: Vec<RecordedEpisode>,
}

/// What the importer is told about a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions {
    /// Dataset name.
    pub dataset: String,
    /// Licence tag.
    pub licence: String,
    /// Mining settings (the smoother's position noise among them).
    pub mining: MiningOptions,
    /// Inverse kinematics settings.
    pub inverse: InverseOptions,
    /// Resample every vehicle's track to this period before inverse kinematics (e.g. 0.2 s
    /// recordings to the model's 0.1 s), s; `None` keeps the recorded period.
    pub resample_s: Option<f64>,
}

/// The piece of `track` (cut at gaps) nearest in time to `t_s` (the one covering it, if any).
fn piece_at(track: &Track, t_s: f64) -> Option<Track> {
    let gap = |p: &Track| p.span_s().map_or(f64::INFINITY, |(a, b)| (a - t_s).max(t_s - b).max(0.0));
    split_at_gaps(track).into_iter().min_by(|x, y| gap(x).total_cmp(&gap(y)))
}

fn thin(points: &[Point2], spacing_m: f64) -> Vec<Point2> {
    let mut out: Vec<Point2> = Vec::new();
    for (k, p) in points.iter().enumerate() {
        let last = k + 1 == points.len();
        if out.last().is_none_or(|q| q.dist(*p) >= spacing_m) || last {
            out.push(*p);
        }
    }
    out
}

/// Paths this close in heading at the conflict run alongside: rad.
const PARALLEL_RAD: f64 = 0.35;
/// A vehicle this close to a lane's centreline drives in that lane: m (half a lane).
const SAME_LANE_M: f64 = 1.8;

/// The interaction's kind read again on the lanes. Short recordings hide the join that map-less
/// mining looks for (a lane change whose paths part again within seconds reads as a crossing), so
/// where the two vehicles run alongside at the conflict: if one of them changes lanes it is the
/// actor, and the kind is a cut-in when it passes the conflict first and a lane change behind
/// otherwise, provided the other vehicle ends in the mover's target lane. If neither changes lanes
/// (they only drove side by side) or the mover leaves the other's lane (it only vacates a place
/// ahead of it), `None`. Interactions at an
/// angle (left turns, crossings, merges) keep their kind. The flag says that the actor is the
/// second of `agents` (the mover was mined as the other vehicle).
pub fn on_lanes(
    it: &crate::mining::Interaction,
    agents: &[RecordedAgent],
    lanes: &LaneletNetwork,
) -> Option<(InteractionKind, bool)> {
    let heading_at = |a: &RecordedAgent| {
        a.states
            .iter()
            .min_by(|x, y| x.position().dist(it.conflict_point).total_cmp(&y.position().dist(it.conflict_point)))
            .map(|s| s.theta_rad)
    };
    let (Some(a), Some(b)) = (agents.first(), agents.get(1)) else { return Some((it.kind, false)) };
    let parallel = heading_at(a)
        .zip(heading_at(b))
        .is_some_and(|(x, y)| v2t_model::geometry::wrap_angle(x - y).abs() < PARALLEL_RAD);
    if !parallel {
        return Some((it.kind, false));
    }
    let moved = |x: &RecordedAgent| lanes.changes_lanes(&x.states.iter().map(State::position).collect::<Vec<_>>());
    let (mover, swap) = match (moved(a), moved(b)) {
        (false, false) => return None,
        (true, false) | (true, true) => (a, false),
        (false, true) => (b, true),
    };
    // It must move into the other's lane: the other ends on the mover's route (its target lane). A
    // mover that leaves the other's lane only vacates a place ahead of it.
    let other = if swap { a } else { b };
    let on_route = v2t_model::path::ReferencePath::from_points(&mover.route)
        .ok()
        .zip(other.states.last())
        .is_some_and(|(route, end)| route.project(end.position()).is_some_and(|f| f.l_m.abs() <= SAME_LANE_M));
    if !on_route {
        return None;
    }
    let kind = if it.first == mover.id { InteractionKind::CutIn } else { InteractionKind::LaneChange };
    Some((kind, swap))
}

/// Why a mined interaction's vehicle could not be kept.
enum Dropped {
    /// No piece of its track near the conflict, or inverse kinematics failed on it.
    NoControls,
    /// It is on no lanelet.
    NoRoute,
}

/// The period episodes of a recording sampled every `recorded_s` get: the resampling period when
/// it is finer.
fn episode_period(options: &ImportOptions, recorded_s: f64) -> f64 {
    options.resample_s.filter(|dt| *dt < recorded_s - 1e-9).unwrap_or(recorded_s)
}

/// One vehicle of an interaction at `conflict_s`: the gap-free piece of its track nearest the
/// conflict, resampled if asked, its controls and its route.
fn recorded_agent(
    track: &Track,
    conflict_s: f64,
    lanes: &LaneletNetwork,
    options: &ImportOptions,
) -> Result<RecordedAgent, Dropped> {
    let mut piece = piece_at(track, conflict_s).ok_or(Dropped::NoControls)?;
    let dt = episode_period(options, piece.dt_s);
    if dt < piece.dt_s {
        piece = piece.resampled(dt).ok_or(Dropped::NoControls)?;
    }
    let inv = to_controls(&piece, &options.inverse).map_err(|_| Dropped::NoControls)?;
    let positions: Vec<Point2> = inv.trajectory.states.iter().map(State::position).collect();
    let (route, route_from) = if lanes.is_empty() {
        (positions, "driven path")
    } else {
        (lanes.route_of(&positions).ok_or(Dropped::NoRoute)?, "lanes")
    };
    Ok(RecordedAgent {
        id: track.id.clone(),
        kind: track.kind,
        dims: track.dims,
        start_s: piece.samples.first().map_or(0.0, |s| s.t_s),
        states: inv.trajectory.states,
        controls: inv.trajectory.controls,
        route: thin(&route, ROUTE_SPACING_M),
        route_from: route_from.to_owned(),
        smoothing_rms_m: inv.smoothing_rms_m,
        vehicle: None,
    })
}

/// Imports one recording (its tracks and lane network): the episodes and the file's summary.
pub fn import_scenario(
    episode: &Episode,
    lanes: &LaneletNetwork,
    file: &str,
    format: &str,
    options: &ImportOptions,
) -> (SourceFile, Vec<RecordedEpisode>) {
    let interactions = mine(episode, &options.mining);
    let mut source = SourceFile {
        file: file.to_owned(),
        recording: episode.id.clone(),
        dataset: options.dataset.clone(),
        licence: options.licence.clone(),
        format: format.to_owned(),
        dt_s: episode.dt_s,
        tracks: episode.tracks.len(),
        vehicles: episode.tracks.iter().filter(|t| t.kind.is_vehicle()).count(),
        mined: interactions.len(),
        kept: 0,
        no_route: 0,
        no_controls: 0,
        not_interaction: 0,
        duplicate_vehicles: 0,
        duplicate_episodes: 0,
        left_turning_vehicles: episode.tracks.iter().filter(|t| turns_left(t)).count(),
    };
    let mut out = Vec::new();
    for mut it in interactions {
        let agents: Result<Vec<RecordedAgent>, Dropped> = [&it.actor, &it.other]
            .into_iter()
            .map(|id| {
                let track = episode.track(id).ok_or(Dropped::NoControls)?;
                recorded_agent(track, it.conflict_time_s, lanes, options)
            })
            .collect();
        let mut agents = match agents {
            Ok(a) => a,
            Err(Dropped::NoRoute) => {
                source.no_route += 1;
                continue;
            }
            Err(Dropped::NoControls) => {
                source.no_controls += 1;
                continue;
            }
        };
        if !lanes.is_empty() {
            let Some((kind, swap)) = on_lanes(&it, &agents, lanes) else {
                source.not_interaction += 1;
                continue;
            };
            it.kind = kind;
            if swap {
                std::mem::swap(&mut it.actor, &mut it.other);
                agents.reverse();
            }
        }
        source.kept += 1;
        out.push(RecordedEpisode {
            id: format!("{}/{}-{}@{:.1}", episode.id, it.actor, it.other, it.conflict_time_s),
            recording: episode.id.clone(),
            file: file.to_owned(),
            dataset: options.dataset.clone(),
            licence: options.licence.clone(),
            dt_s: episode_period(options, episode.dt_s),
            mined: it,
            agents,
        });
    }
    (source, out)
}

/// First line of a recorded corpus file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedHeader {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// Always false: recorded, not simulated.
    pub synthetic: bool,
    /// The imported files.
    pub sources: Vec<SourceFile>,
    /// Number of episode lines that follow.
    pub episodes: usize,
}

/// What can go wrong reading or writing a recorded corpus.
pub type RecordedIoError = crate::jsonl::JsonlError;

/// The corpus as JSON lines.
pub fn to_jsonl(corpus: &RecordedCorpus) -> Result<String, serde_json::Error> {
    let header = RecordedHeader {
        format: FORMAT.to_owned(),
        version: VERSION,
        synthetic: false,
        sources: corpus.sources.clone(),
        episodes: corpus.episodes.len(),
    };
    crate::jsonl::to_string(&header, &corpus.episodes)
}

/// The format name in the first line of a corpus text (either kind), if it has one.
pub fn format_of(text: &str) -> Option<String> {
    let first = text.lines().find(|l| !l.trim().is_empty())?;
    let raw: serde_json::Value = serde_json::from_str(first).ok()?;
    raw.get("format").and_then(|v| v.as_str()).map(str::to_owned)
}

/// Reads a recorded corpus from JSON lines.
pub fn from_jsonl(text: &str) -> Result<RecordedCorpus, RecordedIoError> {
    let (header, episodes): (RecordedHeader, Vec<RecordedEpisode>) =
        crate::jsonl::parse(text, FORMAT, VERSION, |_| true, FORMAT, |h: &RecordedHeader| h.episodes)?;
    Ok(RecordedCorpus { sources: header.sources, episodes })
}

/// Reads a recorded corpus file.
pub fn read_file(path: &std::path::Path) -> Result<RecordedCorpus, RecordedIoError> {
    from_jsonl(&crate::jsonl::read_text(path)?)
}

/// Writes a recorded corpus file: to `<path>.partial`, then renamed into place.
pub fn write_file(corpus: &RecordedCorpus, path: &std::path::Path) -> Result<(), RecordedIoError> {
    let text = to_jsonl(corpus).map_err(|e| RecordedIoError::Json { line: 0, message: e.to_string() })?;
    crate::jsonl::write_atomic(path, &text)
}

/// Counts of a recorded corpus, per dataset and kind, with the PET histogram.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordedStats {
    /// One row per dataset, in first-seen order.
    pub datasets: Vec<DatasetStats>,
    /// Total tracks of every file.
    pub tracks: usize,
    /// Total motor-vehicle tracks.
    pub vehicles: usize,
    /// … of which vehicles an earlier file of their import already held.
    pub duplicate_vehicles: usize,
    /// Total episodes.
    pub episodes: usize,
}

/// One dataset's counts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DatasetStats {
    /// Dataset name.
    pub dataset: String,
    /// Licence tags seen.
    pub licences: Vec<String>,
    /// Files and recordings.
    pub files: usize,
    /// Tracks.
    pub tracks: usize,
    /// Motor-vehicle tracks.
    pub vehicles: usize,
    /// … of which vehicles an earlier file already held (`--dedup`).
    pub duplicate_vehicles: usize,
    /// Interactions dropped as the same two vehicles' as an earlier file's (`--dedup`).
    pub duplicate_episodes: usize,
    /// Vehicles that turn left, interacting or not ([`SourceFile::left_turning_vehicles`]).
    pub left_turning_vehicles: usize,
    /// Sampling periods seen, s.
    pub periods_s: Vec<f64>,
    /// Episodes per interaction kind.
    pub kinds: Vec<(InteractionKind, usize)>,
    /// Mined interactions dropped for want of a route or of controls.
    pub dropped: usize,
    /// PET histogram of the episodes, 0–6 s in bins of 0.5 s.
    pub pet: Histogram,
}

const KINDS: [InteractionKind; 5] = [
    InteractionKind::CutIn,
    InteractionKind::LaneChange,
    InteractionKind::LeftTurn,
    InteractionKind::Crossing,
    InteractionKind::Merge,
];

impl RecordedCorpus {
    /// Counts per dataset.
    pub fn stats(&self) -> RecordedStats {
        let mut rows: Vec<DatasetStats> = Vec::new();
        let row = |rows: &mut Vec<DatasetStats>, dataset: &str| -> usize {
            if let Some(i) = rows.iter().position(|r| r.dataset == dataset) {
                return i;
            }
            rows.push(DatasetStats {
                dataset: dataset.to_owned(),
                licences: Vec::new(),
                files: 0,
                tracks: 0,
                vehicles: 0,
                duplicate_vehicles: 0,
                duplicate_episodes: 0,
                left_turning_vehicles: 0,
                periods_s: Vec::new(),
                kinds: KINDS.iter().map(|k| (*k, 0)).collect(),
                dropped: 0,
                pet: Histogram { lo: 0.0, hi: 6.0, counts: vec![0; 12], underflow: 0, overflow: 0, non_finite: 0 },
            });
            rows.len() - 1
        };
        for s in &self.sources {
            let i = row(&mut rows, &s.dataset);
            let Some(r) = rows.get_mut(i) else { continue };
            r.files += 1;
            r.tracks += s.tracks;
            r.vehicles += s.vehicles;
            r.duplicate_vehicles += s.duplicate_vehicles;
            r.duplicate_episodes += s.duplicate_episodes;
            r.left_turning_vehicles += s.left_turning_vehicles;
            r.dropped += s.no_route + s.no_controls + s.not_interaction;
            if !r.licences.contains(&s.licence) {
                r.licences.push(s.licence.clone());
            }
            if !r.periods_s.iter().any(|p| (p - s.dt_s).abs() < 1e-9) {
                r.periods_s.push(s.dt_s);
            }
        }
        for e in &self.episodes {
            let i = row(&mut rows, &e.dataset);
            let Some(r) = rows.get_mut(i) else { continue };
            if let Some(k) = r.kinds.iter_mut().find(|(k, _)| *k == e.mined.kind) {
                k.1 += 1;
            }
            r.pet.add(e.pet_s());
        }
        RecordedStats {
            tracks: rows.iter().map(|r| r.tracks).sum(),
            vehicles: rows.iter().map(|r| r.vehicles).sum(),
            duplicate_vehicles: rows.iter().map(|r| r.duplicate_vehicles).sum(),
            episodes: self.episodes.len(),
            datasets: rows,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::{Adjacent, Lanelet};
    use crate::tracks::TrackSample;

    fn lanelet(id: &str, y: f64, adj: Option<(&str, bool)>) -> Lanelet {
        let mut l = crate::lanes::straight_lanelet(id, &[-50.0, 50.0, 150.0, 250.0], y);
        let adjacent = adj.map(|(a, _)| Adjacent { id: a.into(), same_direction: true });
        match adj {
            Some((_, true)) => l.adjacent_left = adjacent,
            Some((_, false)) => l.adjacent_right = adjacent,
            None => {}
        }
        l
    }

    /// A cut-in on a two-lane road: `cutter` from y = 3.5 to y = 0 ahead of `follower`.
    fn cut_in() -> (Episode, LaneletNetwork) {
        let track = |id: &str, f: &dyn Fn(f64) -> (f64, f64)| Track {
            id: id.into(),
            dt_s: 0.1,
            kind: AgentKind::Car,
            dims: None,
            samples: (0..100)
                .map(|k| {
                    let t = 0.1 * k as f64;
                    let (x, y) = f(t);
                    TrackSample::at(t, x, y)
                })
                .collect(),
        };
        let follower = track("1", &|t| (10.0 * t, 0.0));
        let cutter = track("2", &|t| {
            let f = ((t - 2.0) / 4.0).clamp(0.0, 1.0);
            let s = f * f * (3.0 - 2.0 * f);
            (12.0 + 11.0 * t, 3.5 * (1.0 - s))
        });
        let lanes =
            LaneletNetwork::new(vec![lanelet("a", 0.0, Some(("b", true))), lanelet("b", 3.5, Some(("a", false)))]);
        (Episode::from_tracks("REC-1", vec![follower, cutter]), lanes)
    }

    fn options() -> ImportOptions {
        ImportOptions {
            dataset: "test".into(),
            licence: "Apache-2.0 (made by this test)".into(),
            mining: MiningOptions::default(),
            inverse: InverseOptions::default(),
            resample_s: None,
        }
    }

    #[test]
    fn a_cut_in_is_imported_with_routes_and_controls() {
        let (e, lanes) = cut_in();
        let (source, episodes) = import_scenario(&e, &lanes, "x.xml", "CommonRoad 2020a", &options());
        assert_eq!((source.tracks, source.vehicles, source.kept), (2, 2, episodes.len()));
        let ep = episodes.iter().find(|e| e.mined.kind == InteractionKind::CutIn).expect("a cut-in");
        assert_eq!(ep.agents[0].id, "2", "the cutter is the actor");
        assert!(ep.agents[0].route.iter().all(|p| p.y.abs() < 1e-9), "cutter's route is the target lane");
        assert_eq!(ep.agents[0].controls.len() + 1, ep.agents[0].states.len());
        assert_eq!(ep.licence, "Apache-2.0 (made by this test)");
        assert_eq!(ep.file, "x.xml");
        assert_eq!(ep.agents[0].route_from, "lanes");
        // Off the network: counted, not kept.
        let far = LaneletNetwork::new(vec![lanelet("z", 100.0, None)]);
        let (source, episodes) = import_scenario(&e, &far, "x.xml", "f", &options());
        assert!(episodes.is_empty() && source.no_route == source.mined && source.mined > 0);
        // No lanes at all (CSV): the driven paths, marked.
        let (_, episodes) = import_scenario(&e, &LaneletNetwork::default(), "x.csv", "CSV", &options());
        assert!(
            !episodes.is_empty() && episodes.iter().all(|e| e.agents.iter().all(|a| a.route_from == "driven path"))
        );
    }

    /// A car that drives 20 m east, turns left on a 15 m radius (90°), and drives 20 m north, at
    /// 8 m/s; a gap of `gap_s` from 1.0 s (none if 0) and `turn_rad` of turn.
    fn turning(turn_rad: f64, gap_s: f64) -> Track {
        let (v, r) = (8.0, 15.0);
        let arc = r * turn_rad;
        let at = |d: f64| -> (f64, f64) {
            if d <= 20.0 {
                (d, 0.0)
            } else if d <= 20.0 + arc {
                let a = (d - 20.0) / r;
                (20.0 + r * a.sin(), r * (1.0 - a.cos()))
            } else {
                let e = d - 20.0 - arc;
                (20.0 + r * turn_rad.sin() + e * turn_rad.cos(), r * (1.0 - turn_rad.cos()) + e * turn_rad.sin())
            }
        };
        let n = ((40.0 + arc) / v / 0.1) as usize;
        let samples = (0..n)
            .map(|k| 0.1 * k as f64)
            .filter(|t| gap_s == 0.0 || !(1.0..1.0 + gap_s).contains(t))
            .map(|t| {
                let (x, y) = at(v * t);
                TrackSample::at(t, x, y)
            })
            .collect();
        Track { id: "7".into(), dt_s: 0.1, kind: AgentKind::Car, dims: None, samples }
    }

    #[test]
    fn a_left_turn_is_kept_as_smoothed_states_of_its_turning_piece() {
        let options = InverseOptions::default();
        let states = left_turn_states(&turning(std::f64::consts::FRAC_PI_2, 0.0), &options).expect("a left turn");
        let total: f64 =
            states.windows(2).map(|w| v2t_model::geometry::wrap_angle(w[1].theta_rad - w[0].theta_rad)).sum();
        assert!((total - std::f64::consts::FRAC_PI_2).abs() < 0.15, "turns {total} rad");
        assert!(states.iter().skip(5).all(|s| (s.speed_mps - 8.0).abs() < 0.3), "the speed stays 8 m/s");
        // Across a gap: the piece after it (the whole turn) is kept, not the 1 s before it.
        let split = left_turn_states(&turning(std::f64::consts::FRAC_PI_2, 0.5), &options).expect("a left turn");
        assert!(split.len() > 50 && split.len() < states.len(), "{} of {} states", split.len(), states.len());
        // 45° is no left turn; a pedestrian is no vehicle.
        assert!(left_turn_states(&turning(std::f64::consts::FRAC_PI_4, 0.0), &options).is_none());
        let walker = Track { kind: AgentKind::Pedestrian, ..turning(std::f64::consts::FRAC_PI_2, 0.0) };
        assert!(left_turn_states(&walker, &options).is_none());
    }

    #[test]
    fn the_corpus_reads_back_and_bad_files_are_named() {
        let (e, lanes) = cut_in();
        let (source, episodes) = import_scenario(&e, &lanes, "x.xml", "CommonRoad 2020a", &options());
        let corpus = RecordedCorpus { sources: vec![source], episodes };
        let text = to_jsonl(&corpus).unwrap();
        assert_eq!(from_jsonl(&text).unwrap(), corpus);
        assert_eq!(format_of(&text).as_deref(), Some(FORMAT));
        let stats = corpus.stats();
        assert_eq!((stats.tracks, stats.episodes), (2, corpus.episodes.len()));
        let mut lines: Vec<&str> = text.lines().collect();
        lines.pop();
        assert!(matches!(from_jsonl(&lines.join("\n")), Err(RecordedIoError::Count { .. })));
        let bad = text.replacen("\"dt_s\":0.1", "\"dt_s\":\"x\"", 2);
        assert!(matches!(from_jsonl(&bad), Err(RecordedIoError::Json { line: 1 | 2, .. })));
        assert!(matches!(from_jsonl("{\"format\":\"v2t-synthetic-corpus\"}"), Err(RecordedIoError::Format { .. })));
        assert!(matches!(from_jsonl(""), Err(RecordedIoError::Empty)));
    }
}
