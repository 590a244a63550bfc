//! `video2track ground`: place a video's semantics on a proving ground's map — rank the fragments of
//! its topology library with the reasons, ground the scenario on the best one that fits, and write
//! the [`GroundedScenario`](v2t_model::grounded::GroundedScenario) the generator and the regulator take.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;
use v2t_ground::{Candidate, Grounding};
use v2t_model::semantics::{ScenarioSemantics, SemanticsError, parse_semantics_json};

/// The proving ground `ground` uses when no `--map` is given.
pub const DEFAULT_MAP: &str = "config/maps/proving_ground.xodr";

/// A semantics file that cannot be read or does not validate.
#[derive(Debug, thiserror::Error)]
pub enum SemanticsFileError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Not valid semantics.
    #[error("{path}: {source}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Why.
        source: SemanticsError,
    },
}

/// Reads and validates a semantics JSON file (the `video2track abstract` output, or hand-written).
pub fn load_semantics(path: &Path) -> Result<ScenarioSemantics, SemanticsFileError> {
    let text =
        std::fs::read_to_string(path).map_err(|source| SemanticsFileError::Read { path: path.to_owned(), source })?;
    parse_semantics_json(&text).map_err(|source| SemanticsFileError::Invalid { path: path.to_owned(), source })
}

/// What `--json` writes: the grounded scenario with how it was found.
#[derive(Debug, Serialize)]
pub struct GroundJson<'a> {
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
pub fn ranking_report(ranking: &[Candidate], top: usize) -> String {
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
pub fn report(g: &Grounding) -> String {
    let mut s = String::new();
    let sc = &g.scenario;
    let _ = writeln!(
        s,
        "grounded on {}: {:?}, {:?} with τ = {:.2} s",
        sc.fragment_id, sc.interaction_type, sc.style, sc.tau_s
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
    use super::*;

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    #[test]
    fn unreadable_and_invalid_semantics_name_the_file() {
        let missing = root().join("config/examples/no_such.json");
        let e = load_semantics(&missing).unwrap_err();
        assert!(matches!(e, SemanticsFileError::Read { .. }) && e.to_string().contains("no_such.json"), "{e}");

        let dir = tempfile::Builder::new().prefix("v2t-ground-cli-").tempdir().unwrap();
        let bad = dir.path().join("bad.json");
        std::fs::write(&bad, "{\"road_topology\": ").unwrap();
        let e = load_semantics(&bad).unwrap_err();
        assert!(matches!(e, SemanticsFileError::Invalid { .. }) && e.to_string().contains("bad.json"), "{e}");
    }

    #[test]
    fn reports_show_the_fragment_agents_conflict_and_reasons() {
        let sem = load_semantics(&root().join("config/examples/semantics_left_turn.json")).unwrap();
        let i = crate::map::inspect(&root().join(DEFAULT_MAP), None).unwrap();
        let g = v2t_ground::ground(&i.map, &i.library, &sem).unwrap();
        let text = report(&g);
        assert!(text.starts_with(&format!("grounded on {}", g.scenario.fragment_id)), "{text}");
        assert!(text.contains("vut") && text.contains("planned PET 2.90 s"), "{text}");
        let view = ranking_report(&g.ranking, 2);
        assert_eq!(view.matches("\n#").count(), 2, "{view}");
        assert!(view.contains("road_type") && view.contains("lexical") && view.contains("more (--top"), "{view}");
    }
}
