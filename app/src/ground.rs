//! `video2track ground`: place a video's semantics on a proving ground's map — rank the fragments of
//! its topology library with the reasons, ground the scenario on the best one that fits, and write
//! the [`GroundedScenario`](v2t_model::grounded::GroundedScenario) the generator and the regulator take.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use serde::Serialize;
use v2t_files::out;
use v2t_ground::{Candidate, Grounding};

/// `ground`'s arguments.
#[derive(Debug, clap::Args)]
pub struct GroundArgs {
    /// Scenario semantics (JSON, as `abstract` writes it), e.g. config/examples/semantics_cut_in.json.
    semantics: PathBuf,
    /// The proving ground's map (.xodr); its annotations `<map>.toml` apply when they exist.
    #[arg(long, default_value = v2t_files::shipped::MAP)]
    map: PathBuf,
    /// Hand annotations (TOML; default: the map's name with .toml, when it exists).
    #[arg(long)]
    annotations: Option<PathBuf>,
    /// Write the grounded scenario (JSON) here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the whole grounding (scenario, routes, planned timing, notes, ranking) as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Show this many ranked fragments with their scores and reasons.
    #[arg(long, default_value_t = 3)]
    top: usize,
}

/// Ranks, grounds, prints and writes.
pub fn run(a: GroundArgs) -> anyhow::Result<()> {
    let sem = v2t_files::read_semantics(&a.semantics)?;
    let inspection = v2t_map::inspect(&a.map, a.annotations.as_deref())?;
    for w in &inspection.map.warnings {
        eprintln!("warning: {}: {w}", a.map.display());
    }
    let ranking = v2t_ground::rank(&inspection.library, &sem);
    out!("{}", ranking_report(&ranking, a.top))?;
    let grounding = v2t_ground::ground(&inspection.map, &inspection.library, &sem)
        .with_context(|| format!("grounding {} on {}", a.semantics.display(), a.map.display()))?;
    out!("{}", report(&grounding))?;
    if let Some(path) = a.out {
        crate::write_json(&path, &grounding.scenario)?;
    }
    if let Some(path) = a.json {
        let doc = GroundJson {
            semantics: a.semantics.display().to_string(),
            map: a.map.display().to_string(),
            grounding: &grounding,
        };
        crate::write_json(&path, &doc)?;
    }
    Ok(())
}

/// What `--json` writes: the grounded scenario with how it was found.
#[derive(Debug, Serialize)]
struct GroundJson<'a> {
    /// Semantics file.
    pub semantics: String,
    /// Map file.
    pub map: String,
    /// The grounding: scenario, routes, planned timing, notes and the full ranking.
    #[serde(flatten)]
    pub grounding: &'a Grounding,
}

/// The ranking view: the best `top` candidates with their per-criterion scores and reasons, then a
/// count of the rest.
fn ranking_report(ranking: &[Candidate], top: usize) -> String {
    let mut s = String::new();
    let feasible = ranking.iter().filter(|c| c.feasible).count();
    let _ = writeln!(s, "ranking: {} fragments, {} feasible", ranking.len(), feasible);
    for (i, c) in ranking.iter().take(top).enumerate() {
        let _ = writeln!(s, "#{} {}", i + 1, c.explain());
    }
    if ranking.len() > top {
        let _ = writeln!(s, "… {} more (--top {} shows them all)", ranking.len() - top, ranking.len());
    }
    s
}

/// The human-readable report of a grounding: the fragment, every agent's start and goal, the
/// conflicts with their planned passage, and the notes.
fn report(g: &Grounding) -> String {
    let mut s = String::new();
    let sc = &g.scenario;
    let _ = writeln!(
        s,
        "grounded on {}: {:?}, {:?} with τ = {:.2} s",
        sc.fragment_id,
        sc.interaction_type,
        sc.target.style(),
        sc.target.tau_s()
    );
    for (agent, route) in sc.agents.iter().zip(&g.routes) {
        let start = &agent.start;
        let _ = writeln!(
            s,
            "  {:<6} {:?}: {} → {} via {} ({:.0} m), from ({:.1}, {:.1}) at {:.1} m/s{}",
            agent.id,
            agent.role,
            route.start_lane,
            route.goal_lane,
            route.maneuvers.join(" + "),
            route.length_m,
            start.position.x,
            start.position.y,
            start.speed_mps,
            start.time_s.map_or(String::new(), |t| format!(", starts at {t:.2} s"))
        );
        let _ = writeln!(s, "         start anchor {}, goal anchor {}", start.anchor_id, agent.goal.anchor_id);
    }
    for (c, t) in sc.conflicts.iter().zip(&g.timing) {
        let _ = writeln!(
            s,
            "  conflict with {} ({:?}) at {} ({:.1}, {:.1}): VUT in the zone {:.2}–{:.2} s, BV {:.2}–{:.2} s, planned PET {:.2} s",
            c.bv_id,
            c.kind,
            c.anchor_id,
            c.point.x,
            c.point.y,
            t.vut_enter_s,
            t.vut_exit_s,
            t.bv_enter_s,
            t.bv_exit_s,
            t.pet_s
        );
    }
    for n in &g.notes {
        let _ = writeln!(s, "  note: {n}");
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use std::path::Path;

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    #[test]
    fn reports_show_the_fragment_agents_conflict_and_reasons() {
        let sem = v2t_files::read_semantics(&root().join("config/examples/semantics_left_turn.json")).unwrap();
        let i = v2t_map::inspect(&root().join(v2t_files::shipped::MAP), None).unwrap();
        let g = v2t_ground::ground(&i.map, &i.library, &sem).unwrap();
        let text = report(&g);
        assert!(text.starts_with(&format!("grounded on {}", g.scenario.fragment_id)), "{text}");
        assert!(text.contains("vut") && text.contains("planned PET 2.90 s"), "{text}");
        let view = ranking_report(&g.ranking, 2);
        assert_eq!(view.matches("\n#").count(), 2, "{view}");
        assert!(view.contains("road_type") && view.contains("lexical") && view.contains("more (--top"), "{view}");
    }
}
