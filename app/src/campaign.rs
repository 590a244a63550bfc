//! `video2track campaign`: the campaign memory of one VUT between the runs of a test campaign on
//! the track — the aim of the next run, a run's measured outcome recorded, what was learned.
//!
//! In the simulated proving ground `video2track sim --regulated --campaign FILE` does all three
//! around one run. On the track, the PET comes from the track's own measurement: `campaign aim`
//! gives the τ to send (`video2track send target --tau …`), `campaign record` takes the run's
//! outcome afterwards. The memory's rules are [`v2t_game::campaign`]'s.

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use v2t_files::outln;
use v2t_game::campaign::{CampaignMemory, RunRecord};
use v2t_model::{Style, Target};

use crate::Usage;

/// `campaign`'s subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum CampaignCommand {
    /// The τ to give the BV in the next run of a test, and whether earlier runs showed τ out of
    /// this VUT's reach.
    Aim(AimArgs),
    /// Record one run's outcome (its aim and the PET the track measured) and update what is learned.
    Record(RecordArgs),
    /// Send what the runs of a test have learned of the VUT (the aim, reach, how it drove its
    /// route, how it was identified to react) to the BV that runs the next one, for the prior it
    /// holds; the BV takes it between the prior's upload and `start`, and says whether it did.
    Send(CampaignSendArgs),
    /// Every test in a memory file: runs, the learned model, the next aim, reach.
    Show {
        /// The memory file (JSON).
        memory: PathBuf,
    },
}

/// Which test of a memory.
#[derive(Debug, clap::Args)]
pub struct TestArgs {
    /// The memory file of this VUT (JSON; one file per VUT).
    memory: PathBuf,
    /// The scenario's name (as in its card or grounded scenario).
    #[arg(long)]
    scenario: String,
    /// Which BV of the scenario (index).
    #[arg(long, default_value_t = 0)]
    bv: usize,
    /// The test's style.
    #[arg(long)]
    style: Style,
    /// The test's target PET τ, s.
    #[arg(long, value_parser = Target::parse_tau)]
    tau: f64,
}

/// `campaign aim`'s arguments.
#[derive(Debug, clap::Args)]
pub struct AimArgs {
    #[command(flatten)]
    test: TestArgs,
}

/// `campaign record`'s arguments.
#[derive(Debug, clap::Args)]
pub struct RecordArgs {
    #[command(flatten)]
    test: TestArgs,
    /// The VUT the runs are against (names a new memory file; must match an existing one's).
    #[arg(long)]
    vut: String,
    /// Where the runs take place (a proving ground's name; `builtin` and `sumo` are the lab's).
    #[arg(long, default_value = "track")]
    world: String,
    /// The τ the BV was given in that run, s (the aim `campaign aim` printed).
    #[arg(long, value_parser = Target::parse_tau, required_unless_present = "free_drive")]
    aim: Option<f64>,
    /// The run was a free drive (the BV parked where it starts, never started; the VUT drove the
    /// test alone): only how the VUT drove its route is learned, from the BV's report
    /// (`--learned`); it is no run of the test.
    #[arg(long, requires = "learned", conflicts_with_all = ["aim", "pet", "opposite_order", "collision"])]
    free_drive: bool,
    /// The PET measured, s (leave out when no PET was measured).
    #[arg(long)]
    pet: Option<f64>,
    /// The vehicles passed in the order opposite to the style.
    #[arg(long)]
    opposite_order: bool,
    /// The run ended in a collision.
    #[arg(long)]
    collision: bool,
    /// The session log of `video2track serve --log` that holds what the BV reported it learned in
    /// this run (how the VUT drove its route, how it reacted): the memory learns it too.
    #[arg(long, requires_all = ["from_bv", "prior_id"])]
    learned: Option<PathBuf>,
    /// With --learned: the BV that ran it (its id).
    #[arg(long, requires = "learned")]
    from_bv: Option<String>,
    /// With --learned: the prior of the run (its id).
    #[arg(long, requires = "learned")]
    prior_id: Option<u64>,
}

/// `campaign send`'s arguments.
#[derive(Debug, clap::Args)]
pub struct CampaignSendArgs {
    #[command(flatten)]
    test: TestArgs,
    /// The BV that runs the test (its id; one BV).
    #[arg(long)]
    to: String,
    /// The id of the prior the BV holds for the run (as `video2track upload` printed it).
    #[arg(long)]
    prior_id: u64,
    #[command(flatten)]
    shot: crate::link::OneShotArgs,
}

/// Runs a `campaign` subcommand.
pub fn run(c: CampaignCommand) -> anyhow::Result<()> {
    match c {
        CampaignCommand::Aim(a) => {
            let target = Target::new(a.test.tau, a.test.style)?;
            match load(&a.test.memory)? {
                Some(m) => match m.case(&a.test.scenario, a.test.bv, target) {
                    Some(case) => {
                        outln!("{}", case.aim(target).tau_s())?;
                        eprintln!("{}", v2t_lab::campaign::case_line(case, target));
                    }
                    None => {
                        outln!("{}", target.tau_s())?;
                        eprintln!("no run of this test against {} yet: aim at τ", m.vut);
                    }
                },
                None => {
                    outln!("{}", target.tau_s())?;
                    eprintln!("{} does not exist yet: run 1 aims at τ", a.test.memory.display());
                }
            }
            Ok(())
        }
        CampaignCommand::Record(a) => record(a),
        CampaignCommand::Send(a) => send(a),
        CampaignCommand::Show { memory } => {
            let m = load(&memory)?.ok_or_else(|| Usage(format!("{}: no such memory file", memory.display())))?;
            outln!("campaign memory of VUT `{}` in `{}`: {} tests", m.vut, m.world, m.cases.len())?;
            for c in &m.cases {
                outln!(
                    "  {} BV {} {} τ {:.2} s: {}",
                    c.scenario,
                    c.bv,
                    c.target.style(),
                    c.target.tau_s(),
                    v2t_lab::campaign::case_line(&c.memory, c.target)
                )?;
            }
            Ok(())
        }
    }
}

fn send(a: CampaignSendArgs) -> anyhow::Result<()> {
    let target = Target::new(a.test.tau, a.test.style)?;
    if a.to == "all" || !v2t_wire::link::topics::valid_id(&a.to) {
        return Err(Usage(format!(
            "--to must name one BV (1 to 64 letters, digits, `_` or `-`), got `{}`: what a test learned is for the BV that runs it",
            a.to
        ))
        .into());
    }
    let memory = load(&a.test.memory)?;
    let case = memory.as_ref().and_then(|m| m.case(&a.test.scenario, a.test.bv, target));
    let (aim, learned) = match case {
        Some(c) => (c.aim(target), v2t_lab::campaign::learned_of(c)),
        None => (target, v2t_edge::campaign::Learned::default()),
    };
    outln!("prior {}: aim {aim}; {}", a.prior_id, learned.summary())?;
    a.shot.send(&a.to, v2t_wire::link::CloudBody::Campaign(learned.upload(a.prior_id, aim)))
}

fn record(a: RecordArgs) -> anyhow::Result<()> {
    let target = Target::new(a.test.tau, a.test.style)?;
    if let Some(p) = a.pet
        && !(p.is_finite() && (0.0..=3600.0).contains(&p))
    {
        return Err(Usage(format!("--pet must lie in [0, 3600] s, got {p}")).into());
    }
    for (field, s) in [("--vut", &a.vut), ("--world", &a.world)] {
        if s.is_empty() || s.len() > 128 || s.chars().any(char::is_control) {
            return Err(Usage(format!("{field} must be 1 to 128 printable characters")).into());
        }
    }
    let lesson = match (&a.learned, &a.from_bv, a.prior_id) {
        (Some(log), Some(bv), Some(prior_id)) => Some(lesson_of(log, bv, prior_id, a.aim)?),
        _ => None,
    };
    let mut memory = load_for(&a.test.memory, &a.vut, &a.world)?;
    let case = memory.case_mut(&a.test.scenario, a.test.bv, target);
    if a.free_drive {
        // No PET, no aim, nothing for the reaction model: a free drive shows the VUT's route.
        let route = lesson.and_then(|(_, l)| l.route).ok_or_else(|| {
            Usage("--free-drive: the BV's report holds no route (the VUT was not seen through its zone)".into())
        })?;
        case.learn_free_drive(target, &route);
        eprintln!(
            "free drive: the VUT's route learned to {:.0} m",
            (route.speeds_mps.len().saturating_sub(1)) as f64 * route.step_m
        );
        let line = v2t_lab::campaign::case_line(case, target);
        save(&a.test.memory, &memory)?;
        outln!("{line}")?;
        return Ok(());
    }
    // clap makes --aim required without --free-drive.
    let aim_s = a.aim.ok_or_else(|| Usage("--aim is required".into()))?;
    let (report, learned) = match lesson {
        Some((r, l)) => (Some(r), l),
        None => (None, v2t_edge::campaign::Learned::default()),
    };
    case.record(
        target,
        RunRecord {
            aim_s,
            pet_s: a.pet,
            order_ok: !a.opposite_order,
            collision: a.collision,
            learned_route: report.as_ref().is_some_and(|r| r.started_with_route),
            reaction_prior: report.as_ref().is_some_and(|r| r.started_with_reaction),
        },
    );
    if let Some(route) = &learned.route {
        case.learn_route(target, route);
    }
    if let Some(reaction) = &learned.reaction {
        case.learn_reaction(target, reaction);
    }
    if report.is_some() {
        eprintln!("from the BV's report: {}", learned.summary());
    }
    let line = v2t_lab::campaign::case_line(case, target);
    save(&a.test.memory, &memory)?;
    outln!("{line}")?;
    Ok(())
}

/// What BV `bv` reported it learned in the run of prior `prior_id` (the last such report in the
/// session log `log`), checked by the regulator's rules; the run must have aimed at `aim_s` when
/// one is given.
fn lesson_of(
    log: &Path,
    bv: &str,
    prior_id: u64,
    aim_s: Option<f64>,
) -> anyhow::Result<(v2t_wire::link::RunLearned, v2t_edge::campaign::Learned)> {
    let text = v2t_files::bounds::read_text_within(log, v2t_files::bounds::SESSION_LOG)
        .map_err(|e| Usage(format!("{}: {e}", log.display())))?;
    let leaf = format!("/bv/{bv}/{}", v2t_wire::link::topics::LEARNED);
    let mut found = None;
    for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let bad = |why: String| Usage(format!("{} line {}: {why}", log.display(), i + 1));
        let v: serde_json::Value = serde_json::from_str(line).map_err(|e| bad(format!("not JSON: {e}")))?;
        if !v.get("topic").and_then(|t| t.as_str()).is_some_and(|t| t.ends_with(&leaf)) {
            continue;
        }
        let r: v2t_wire::link::RunLearned = serde_json::from_value(v.get("message").cloned().unwrap_or_default())
            .map_err(|e| bad(format!("not a run's report: {e}")))?;
        if r.prior_id == prior_id {
            r.check().map_err(|e| bad(e.to_string()))?;
            found = Some(r);
        }
    }
    let r = found.ok_or_else(|| {
        Usage(format!("{}: no report of what {bv} learned in the run of prior {prior_id}", log.display()))
    })?;
    if let Some(aim_s) = aim_s
        && (r.aim.tau_s() - aim_s).abs() > 1e-6
    {
        return Err(Usage(format!(
            "--aim {aim_s} s, but the run of prior {prior_id} aimed at {} s (the BV's report)",
            r.aim.tau_s()
        ))
        .into());
    }
    let up = v2t_wire::link::CampaignUpload {
        prior_id,
        aim: r.aim,
        below_reach: None,
        route: r.route.clone(),
        reaction: r.reaction.clone(),
    };
    let learned = v2t_edge::campaign::Learned::from_upload(&up)
        .map_err(|e| Usage(format!("{}: the report of prior {prior_id}: {e}", log.display())))?;
    Ok((r, learned))
}

/// Reads a memory file: `None` when it does not exist; a malformed one is bad input naming the file.
pub(crate) fn load(path: &Path) -> anyhow::Result<Option<CampaignMemory>> {
    let text = match v2t_files::bounds::read_text_within(path, v2t_files::bounds::CAMPAIGN_MEMORY) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Usage(format!("{}: {e}", path.display())).into()),
    };
    v2t_lab::campaign::memory_from_json(&text)
        .map(Some)
        .map_err(|e| Usage(format!("{}: not a campaign memory: {e}", path.display())).into())
}

/// The memory of `vut` in `world` from `path` (an empty one when the file does not exist yet); a
/// file learned from another VUT or world is bad input.
pub(crate) fn load_for(path: &Path, vut: &str, world: &str) -> anyhow::Result<CampaignMemory> {
    let memory = load(path)?.unwrap_or_else(|| CampaignMemory::new(vut, world));
    memory.check_vut(vut, world).map_err(|e| Usage(format!("{}: {e}", path.display())))?;
    Ok(memory)
}

/// Writes a memory file whole (a temporary file renamed over it: a run never leaves half a file).
pub(crate) fn save(path: &Path, memory: &CampaignMemory) -> anyhow::Result<()> {
    let text = v2t_lab::campaign::memory_json(memory).context("serializing the campaign memory")?;
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text + "\n").with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("replacing {}", path.display()))?;
    Ok(())
}
