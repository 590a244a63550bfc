//! The report of test campaigns: every run of every campaign as a cell (its PET over the aim it was
//! run at), and the learning over a campaign per VUT.

use super::{CampaignReport, CampaignRun};
use crate::report::experiment::{CaseView, ExperimentView};
use crate::report::num;
use crate::report::plot::{Level, LinePlot, Series, colour};

/// Test campaigns: every run of every campaign, with its aim; the learning over a campaign first.
impl ExperimentView for CampaignReport {
    fn case_views(&self) -> Vec<CaseView> {
        let r = self;
        r.cases
            .iter()
            .map(|c| {
                let pets: Vec<f64> = c.runs.iter().filter_map(|x| x.pet_s).collect();
                let mean = (!pets.is_empty()).then(|| pets.iter().sum::<f64>() / pets.len() as f64);
                CaseView {
                    scenario: c.scenario.clone(),
                    vut: c.vut.clone(),
                    method: String::new(),
                    style: c.style.to_string(),
                    tau_s: c.tau_s,
                    unmeasured: c.runs.len() - pets.len(),
                    collisions: c.runs.iter().filter(|x| x.collision).count(),
                    error_rel: mean.map(|m| (m - c.tau_s).abs() / c.tau_s),
                    reachable: c.reachable,
                    pets_s: pets,
                    run_header: std::iter::once("campaign".to_owned())
                        .chain((1..=r.runs_per_campaign).map(|k| format!("run {k}")))
                        .collect(),
                    runs: campaign_rows(&c.runs),
                }
            })
            .collect()
    }

    fn lead(&self) -> String {
        learning(self)
    }
}

/// One row per campaign, one cell per run: its PET over the aim it was run at (the aim in
/// grey), a wrong order, a collision and a "τ out of reach" report marked.
fn campaign_rows(runs: &[CampaignRun]) -> Vec<Vec<String>> {
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut current: Option<u64> = None;
    for x in runs {
        if current != Some(x.campaign) {
            current = Some(x.campaign);
            rows.push(vec![format!("{} <span class=\"muted\">(seeds {}…)</span>", x.campaign, x.seed)]);
        }
        let pet = if x.failed { "failed".to_owned() } else { num(x.pet_s, 2) };
        let mut marks = String::new();
        if !x.order_ok {
            marks.push_str(" order");
        }
        if x.collision {
            marks.push_str(" collision");
        }
        if x.below_reach.is_some() {
            marks.push_str(" ↓reach");
        }
        let cell = if marks.is_empty() && !x.failed {
            format!("{pet}<br><small class=\"muted\">{:.2}</small>", x.aim_s)
        } else {
            format!("<span class=\"warn\">{pet}{marks}</span><br><small class=\"muted\">{:.2}</small>", x.aim_s)
        };
        if let Some(row) = rows.last_mut() {
            row.push(cell);
        }
    }
    rows
}

/// A campaign's learning: per VUT, the mean steering error of the k-th run of every campaign.
fn learning(r: &CampaignReport) -> String {
    let mut vuts: Vec<&str> = Vec::new();
    for c in &r.cases {
        if !vuts.contains(&c.vut.as_str()) {
            vuts.push(&c.vut);
        }
    }
    let series: Vec<Series> = vuts
        .iter()
        .enumerate()
        .map(|(i, vut)| {
            let points = (0..r.runs_per_campaign)
                .filter_map(|k| {
                    let errs: Vec<f64> = r
                        .cases
                        .iter()
                        .filter(|c| c.vut == *vut && c.reachable != Some(false))
                        .filter_map(|c| c.per_run.get(k).map(|s| s.error_rel))
                        .collect();
                    (!errs.is_empty()).then(|| ((k + 1) as f64, 100.0 * errs.iter().sum::<f64>() / errs.len() as f64))
                })
                .collect();
            Series::line(*vut, points, colour(i))
        })
        .collect();
    let plot = LinePlot {
        title: "Learning over a campaign (targets the VUT allows)".into(),
        x_label: "run of the campaign".into(),
        y_label: "mean steering error (%)".into(),
        series,
        levels: vec![Level { y: 10.0, label: "10 %".into() }],
        y_range: None,
        x_range: Some((0.5, r.runs_per_campaign as f64 + 0.5)),
        cursor: false,
        markers: false,
    };
    format!(
        "<h2>Steering over a campaign, per VUT</h2>{}<p class=\"muted\">Under \"Runs, case by case\" every cell \
         holds a run's PET<sub>min</sub> over the aim the BV was run at (grey), s; a wrong order, a collision and a \
         \"τ out of reach\" report (↓reach) are marked.</p>",
        plot.svg("learning")
    )
}
