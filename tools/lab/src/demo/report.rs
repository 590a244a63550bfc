//! The demo's HTML report: the results table, then every scenario's run as the report generator
//! draws it ([`crate::report::run`]) on the proving ground's map.

use std::path::Path;

use v2t_sim::realism::VehicleRealism;
use v2t_sim::runfile::RunFile;

use crate::report::{Page, esc, num, pct, run, table};

use super::Summary;

pub(super) fn html(summary: &Summary, runs: &[RunFile], map: &v2t_map::Map, map_path: &Path) -> String {
    let mut page = Page::new("Video2Track demo");
    page.provenance = vec![
        "Semantics replayed from the shipped hand-written VLM exchanges (cassettes): no model was asked.".into(),
        format!("Grounded on the proving ground {}; prior: {}.", map_path.display(), summary.prior),
        "Each run closes the loop through the BV's onboard processes (iceoryx2, CAN frames) and the simulated \
         proving ground; the VUT is a driver model written by this project."
            .into(),
        "The left turn with the VUT turning has no video: its PET label (2.40 s) is made up.".into(),
        format!("Wall time {:.1} s.", summary.wall_s),
    ];
    let rows: Vec<Vec<String>> = summary
        .scenarios
        .iter()
        .map(|s| {
            vec![
                format!("<a href=\"#{}\">{}</a>", esc(&s.name), esc(&s.name)),
                esc(&s.style),
                format!("{:.2}", s.pet_video_s),
                num(s.pet_min_track_s, 2),
                pct(s.fidelity_error_rel),
                match s.order_ok {
                    Some(true) => "as asked".into(),
                    Some(false) => "<span class=\"warn\">wrong</span>".into(),
                    None => "–".into(),
                },
                if s.collision { "<span class=\"warn\">yes</span>".into() } else { "no".into() },
                num(s.min_distance_m, 2),
                realism_cells(s.bv_realism.as_ref()),
            ]
        })
        .collect();
    let mut body = table(
        "summary",
        &[
            "scenario",
            "style",
            "PET video (s)",
            "PET<sub>min</sub> track (s)",
            "fidelity error",
            "order",
            "collision",
            "min distance (m)",
            "BV realism: class, W<sub>1</sub> accel (m/s²), W<sub>1</sub> jerk (m/s³)",
        ],
        &rows,
    );
    body.push_str(
        "<p class=\"muted\">Fidelity error: |PET<sub>min</sub> on the track − the video's PET| / the video's PET. \
         BV realism: W<sub>1</sub> distances of the BV's longitudinal acceleration and jerk to recorded human driving \
         (NGSIM) of its manoeuvre class.</p>",
    );
    for (s, r) in summary.scenarios.iter().zip(runs) {
        let file = |suffix: &str| format!("{}.{suffix}", s.name);
        let input = run::RunInput {
            id: s.name.clone(),
            title: format!("{} — {} ({}), video PET {:.2} s", s.name, s.interaction, s.style, s.pet_video_s),
            run: r,
            map: Some(map),
            ground: format!("the proving ground {}, fragment {}", map_path.display(), s.fragment),
            links: [
                ("run (JSON)", "run.json"),
                ("recording (MCAP, Foxglove)", "mcap"),
                ("OpenSCENARIO", "xosc"),
                ("video (mp4)", "mp4"),
                ("prior", "prior.json"),
                ("grounded scenario", "grounded.json"),
                ("semantics", "semantics.json"),
            ]
            .iter()
            .filter(|(_, suffix)| s.files.iter().any(|f| f.ends_with(&file(suffix))))
            .map(|(label, suffix)| ((*label).to_owned(), file(suffix)))
            .collect(),
            facts: vec![("prior".into(), esc(&s.prior))],
        };
        body.push_str(&run::section(&input));
    }
    page.body = body;
    page.html()
}

/// The BV-realism cell of a row: class, W₁ of acceleration and of jerk.
fn realism_cells(r: Option<&VehicleRealism>) -> String {
    let Some(r) = r else { return "–".into() };
    match &r.realism {
        Some(m) => {
            format!("{}, {}, {}", esc(r.class.name()), num(Some(m.w1_accel_mps2), 3), num(Some(m.w1_jerk_mps3), 3))
        }
        None => format!("{}, no human reference", esc(r.class.name())),
    }
}
