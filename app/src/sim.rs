//! `video2track sim`, `replay` and `render`: one run in the simulated proving ground, measured
//! again from its recording, or drawn as a video.

use std::path::{Path, PathBuf};

use v2t_files::{out, outln};
use v2t_sim::recording;
use v2t_sim::vut::VutModel;

use crate::write_json;

/// `sim`'s arguments.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("regulators").args(["regulated", "free_drive"])))]
pub struct SimArgs {
    /// Scenario card (TOML), e.g. config/scenarios/left_turn_basic.toml.
    card: PathBuf,
    /// Random seed of sensor noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// VUT driver model of the builtin world (default: the card's).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
    vut: Option<String>,
    #[command(flatten)]
    world: crate::world::WorldArgs,
    /// Write the results and the full trace as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Record the run as MCAP (truth, scene, commands, predicted PET) to this file.
    #[arg(long)]
    mcap: Option<PathBuf>,
    /// Recorded human driving per manoeuvre class: the reference of the realism lines (default:
    /// the shipped config/realism/human_reference.json when run from the repository).
    #[arg(long)]
    human_reference: Option<PathBuf>,
    /// The BVs regulate (the onboard regulator, `--regulator`) instead of following their
    /// references.
    #[arg(long)]
    regulated: bool,
    /// With --regulated or --free-drive: the regulator's settings (TOML; in a free drive the parked BVs' regulators measure the VUT's route with them).
    #[arg(long, default_value = v2t_files::shipped::REGULATOR, requires = "regulators")]
    regulator: PathBuf,
    /// With --regulated: one run of a test campaign. The memory of this VUT (JSON; made when
    /// missing) gives each BV its aim and what earlier runs showed about reach; the run's outcome
    /// is recorded in it afterwards. With --free-drive: how the VUT drove its route is recorded in
    /// it for this test, for the regulated runs that follow.
    #[arg(long)]
    campaign: Option<PathBuf>,
    /// A free drive: every BV stands where it starts and the VUT drives the test alone, as a test
    /// engineer drives the ADS through the test before it. Prints how the VUT drove its route up
    /// to each BV's zone; with --campaign, records it for this test.
    #[arg(long, conflicts_with = "regulated")]
    free_drive: bool,
    /// With --regulated: the regulator runs in the cloud, across this simulated network (TOML, as
    /// in config/network): the BV reports its state and the VUT's, follows the plans that reach it.
    #[arg(long, requires = "regulated", conflicts_with_all = ["campaign", "cloud_broker"])]
    network: Option<PathBuf>,
    /// With --regulated: the regulator runs in a cloud process (`video2track regulate`) reached
    /// through this MQTT broker (mqtt://host:port), in real time: the run takes as long as its
    /// scenario. Needs --cloud-key and --start-unix-ms.
    #[arg(long, requires_all = ["regulated", "cloud_key", "start_unix_ms"], conflicts_with = "campaign")]
    cloud_broker: Option<String>,
    /// With --cloud-broker: the cloud's public key (64 hex digits), which every plan must be signed with.
    #[arg(long, requires = "cloud_broker")]
    cloud_key: Option<PathBuf>,
    /// With --cloud-broker: when the test starts, Unix ms (the same for `regulate`).
    #[arg(long, requires = "cloud_broker")]
    start_unix_ms: Option<u64>,
    /// With --cloud-broker: the fleet and the BV's id on the link.
    #[arg(long, default_value = "sim", requires = "cloud_broker")]
    fleet: String,
    /// With --cloud-broker: the BV's id on the link.
    #[arg(long, default_value = "bv1", requires = "cloud_broker")]
    bv_id: String,
    /// Write the run's HTML report (map, footprints and time slider, plots, zone occupancy, the
    /// regulator's status, realism) to this file.
    #[arg(long)]
    report: Option<PathBuf>,
    /// With --report: the map (OpenDRIVE) drawn under the run; the bundled cards run on the
    /// proving ground's lanes.
    #[arg(long, default_value = v2t_files::shipped::MAP, requires = "report")]
    report_map: PathBuf,
}

impl SimArgs {
    /// Where a cloud-regulated BV's regulator is.
    fn cloud(&self) -> crate::regulate::CloudSide {
        crate::regulate::CloudSide {
            regulator: self.regulator.clone(),
            network: self.network.clone(),
            broker: self.cloud_broker.clone(),
            key: self.cloud_key.clone(),
            start_unix_ms: self.start_unix_ms,
            fleet: self.fleet.clone(),
            bv_id: self.bv_id.clone(),
        }
    }
}

/// Runs the card and prints what happened.
pub fn run(a: SimArgs) -> anyhow::Result<()> {
    let scenario = v2t_sim::files::load_scenario(&a.card)?;
    // The report's map, read before the run.
    let map = match &a.report {
        Some(_) => Some(v2t_map::Map::load(&a.report_map).map_err(crate::BadFile::of)?),
        None => None,
    };
    let model = match &a.vut {
        Some(name) => Some(name.parse::<VutModel>().map_err(crate::Usage)?),
        None => None,
    };
    let human = v2t_files::human_reference_or_shipped(a.human_reference.as_deref())?;
    let sumo = a.world.sumo(false)?;
    if sumo.is_some() && model.is_some() {
        return Err(
            crate::Usage("--vut names a builtin driver model; with --world sumo use --sumo-driver".to_owned()).into()
        );
    }
    let vut = match &sumo {
        Some(s) => match s.drivers.as_slice() {
            [driver] => v2t_lab::vut::Vut::Sumo { world: &s.world, driver },
            _ => return Err(crate::Usage("sim runs one SUMO driver: give --sumo-driver once".to_owned()).into()),
        },
        None => v2t_lab::vut::Vut::Builtin(model.unwrap_or(scenario.vut.default_model)),
    };
    if a.campaign.is_some() && !a.regulated && !a.free_drive {
        return Err(crate::Usage("--campaign needs --regulated or --free-drive".to_owned()).into());
    }
    let (outcome, plans) = if a.free_drive {
        (free_drive(&a, &scenario, &vut)?, None)
    } else if a.regulated && (a.network.is_some() || a.cloud_broker.is_some()) {
        (crate::regulate::cloud_regulated_run(&a.cloud(), &scenario, &vut, a.seed)?, None)
    } else if a.regulated {
        let run = regulated(&a, &scenario, &vut)?;
        let plans = run.plans();
        (run.outcome, Some(plans))
    } else {
        (v2t_lab::sim::run_reference(&scenario, &vut, a.seed)?, None)
    };
    out!("{}", v2t_lab::sim::report(&outcome, vut.world()))?;
    let realism = match &human {
        Some(h) => {
            let r = v2t_sim::realism::measure_run(&scenario, &outcome, h).map_err(|e| crate::Usage(e.to_string()))?;
            out!("{}", v2t_lab::sim::realism_report(&r, h))?;
            Some(r)
        }
        None => None,
    };
    if let Some(path) = &a.mcap {
        let first = plans.as_ref().and_then(|p| p.first()).map_or(&[][..], Vec::as_slice);
        recording::write_with_plans(&outcome, first, path)?;
        outln!("wrote {}", path.display())?;
    }
    let file = v2t_sim::runfile::RunFile { realism, regulator: plans, ..v2t_sim::runfile::RunFile::of(&outcome) };
    if let Some(path) = &a.json {
        write_json(path, &file)?;
    }
    if let Some(path) = &a.report {
        let place = format!("{}; scenario card {}", vut.world().provenance(), a.card.display());
        let page = v2t_lab::report::run::page(
            &file,
            map.as_ref(),
            &a.report_map,
            &place,
            path,
            &[("run (JSON)", a.json.as_deref()), ("recording (MCAP)", a.mcap.as_deref())],
        );
        std::fs::write(path, page).map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        outln!("wrote {}", path.display())?;
    }
    Ok(())
}

/// A free drive of the test ([`v2t_lab::campaign::free_drive_run`]): prints how the VUT drove its
/// route up to each BV's zone, as each parked BV's regulator (`--regulator`) measured it, and, with
/// `--campaign`, records it in the memory for this test.
fn free_drive(
    a: &SimArgs,
    scenario: &v2t_sim::scenario::Scenario,
    vut: &v2t_lab::vut::Vut<'_>,
) -> anyhow::Result<v2t_sim::runner::RunOutcome> {
    use v2t_lab::campaign;
    let mut memory = a
        .campaign
        .as_deref()
        .map(|path| crate::campaign::load_for(path, &vut.name(), vut.world().as_str()))
        .transpose()?;
    let settings: v2t_game::regulator::RegulatorParams = v2t_files::load_toml(&a.regulator)?;
    let drive = campaign::free_drive_run(&settings, scenario, vut, a.seed)?;
    outln!("free drive: every BV parked where it starts, the VUT alone; each BV's regulator measures its route")?;
    for (i, route) in drive.routes.iter().enumerate() {
        match route {
            Some(route) => {
                let slowest =
                    route.slowest().map_or_else(String::new, |(at, v)| format!(", slowest {v:.1} m/s at {at:.0} m"));
                outln!("  BV {i}: the VUT's route learned to {:.0} m{slowest}", route.end_m())?;
                if let Some(m) = memory.as_mut() {
                    m.case_mut(&scenario.name, i, scenario.target).learn_free_drive(scenario.target, route);
                }
            }
            None => outln!("  BV {i}: the VUT never passed this BV's zone (as the BV measured it): nothing learned")?,
        }
    }
    if let (Some(m), Some(path)) = (memory.as_ref(), &a.campaign) {
        crate::campaign::save(path, m)?;
        outln!(
            "recorded in {} for {} {} τ {:.2} s",
            path.display(),
            scenario.name,
            scenario.target.style(),
            scenario.target.tau_s()
        )?;
    }
    Ok(drive.outcome)
}

/// One run with regulated BVs, as one run of a campaign when asked.
fn regulated(
    a: &SimArgs,
    scenario: &v2t_sim::scenario::Scenario,
    vut: &v2t_lab::vut::Vut<'_>,
) -> anyhow::Result<v2t_lab::campaign::RegulatedRun> {
    use v2t_game::reaction::ReactionPosterior;
    use v2t_lab::campaign;
    let settings: v2t_game::regulator::RegulatorParams = v2t_files::load_toml(&a.regulator)?;
    let (name, world) = (vut.name(), vut.world().as_str());
    let mut memory = a.campaign.as_deref().map(|path| crate::campaign::load_for(path, &name, world)).transpose()?;
    let line = |m: &v2t_game::campaign::CampaignMemory, i: usize| {
        m.case(&scenario.name, i, scenario.target)
            .map_or_else(|| "no earlier run: aims at τ".to_owned(), |c| campaign::case_line(c, scenario.target))
    };
    if let Some(m) = &memory {
        for i in 0..scenario.bvs.len() {
            outln!("campaign, BV {i} before the run: {}", line(m, i))?;
        }
    }
    let run = campaign::regulated_run(&settings, scenario, vut, a.seed, memory.as_ref())?;
    for (i, (aim, below)) in run.aims.iter().zip(&run.below_reach).enumerate() {
        let reach = below.map_or_else(String::new, |b| {
            format!(
                "; the regulator reported τ out of the VUT's reach ({:?}{})",
                b.cause,
                b.pet_bound_s.map_or_else(String::new, |x| format!(", PET bound {x:.2} s"))
            )
        });
        outln!("BV {i} regulated, aiming at {:.2} s for τ {:.2} s{reach}", aim.tau_s(), scenario.target.tau_s())?;
        if let Some(id) = run.reactions.get(i).cloned().flatten().as_ref().and_then(ReactionPosterior::identified) {
            outln!("BV {i}'s regulator identified the VUT by the end of the run: it {id}")?;
        }
    }
    if let (Some(m), Some(path)) = (memory.as_mut(), &a.campaign) {
        campaign::record_run(m, scenario, &run);
        crate::campaign::save(path, m)?;
        for i in 0..scenario.bvs.len() {
            outln!("campaign, BV {i} after the run: {}", line(m, i))?;
        }
        outln!("wrote {}", path.display())?;
    }
    Ok(run)
}

/// `replay`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    /// The recording (.mcap).
    recording: PathBuf,
    /// Write the recomputed result as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// Measures the recording again; an error when anything differs.
pub fn replay(a: ReplayArgs) -> anyhow::Result<()> {
    let r = recording::replay(&a.recording).map_err(crate::BadFile::of)?;
    let printed =
        out!("{}", recording::report(&a.recording, &r)).map_err(anyhow::Error::from).and_then(|()| match a.json {
            Some(path) => write_json(&path, &r.recomputed),
            None => Ok(()),
        });
    // Metrics that differ are the answer (exit 1) even when stdout's reader went away early.
    anyhow::ensure!(r.matches(), "the recomputed metrics differ from the recorded ones");
    printed
}

/// `render`'s arguments.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// The run (JSON written by `video2track sim --json`).
    run: PathBuf,
    /// The video to write, e.g. run.mp4.
    #[arg(short, long)]
    out: PathBuf,
    /// Frames per second (poses between the run's 10 Hz samples are interpolated).
    #[arg(long, default_value_t = 10)]
    fps: u32,
    /// Width, px (even); the height is 9/16 of it.
    #[arg(long, default_value_t = 960)]
    width: u32,
    /// The run's scenario card: footprints and routes (default: 4.8 m × 1.85 m, driven paths).
    #[arg(long)]
    card: Option<PathBuf>,
    /// A map (.xodr) whose lanes are drawn underneath.
    #[arg(long)]
    map: Option<PathBuf>,
}

/// Draws the run and pipes the frames to ffmpeg.
pub fn render(a: RenderArgs) -> anyhow::Result<()> {
    use v2t_export::video;
    let opts = video::RenderOptions { fps: a.fps, width: a.width };
    opts.validate()?;
    let scene = video::load_scene(&a.run, a.card.as_deref(), a.map.as_deref())?;
    let done = video::encode(&scene, &opts, &a.out, Path::new("ffmpeg"))?;
    let (t0, t1) = scene.time_span();
    outln!(
        "{}: {} vehicles, {:.1} s  |  {} frames at {} fps, {}x{}, {}",
        scene.name,
        scene.vehicles.len(),
        t1 - t0,
        done.frames,
        a.fps,
        done.width,
        done.height,
        done.encoder
    )?;
    outln!("wrote {}", a.out.display())?;
    Ok(())
}
