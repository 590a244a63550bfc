//! The parts of an experiment's or campaign's report: its tables (the markdown the experiment
//! prints, as HTML), every run's PET per case as strips (one plot per VUT: figures are never pooled
//! across VUT models), the steering error against τ, the methods side by side, and each case's
//! runs to drill down to.

use std::fmt::Write as _;

use super::plot::{Level, LinePlot, Series, Strip, StripPlot, colour};
use super::{esc, num, pct, table};

/// One case of an experiment (a scenario, style, τ, VUT, and method or setting), with its runs.
#[derive(Debug, Clone, Default)]
pub struct CaseView {
    /// The scenario.
    pub scenario: String,
    /// The VUT model or SUMO driver.
    pub vut: String,
    /// The method (the four methods) or setting (a realism weight, a network); empty: none.
    pub method: String,
    /// `rush` or `yield`.
    pub style: String,
    /// The target PET, s.
    pub tau_s: f64,
    /// PET_min of every run with a measured PET, s.
    pub pets_s: Vec<f64>,
    /// Runs without a measured PET.
    pub unmeasured: usize,
    /// Runs with a collision.
    pub collisions: usize,
    /// The case's steering error |mean PET − τ| / τ.
    pub error_rel: Option<f64>,
    /// Whether any BV can reach τ against this VUT; `Some(false)` is marked, not hidden.
    pub reachable: Option<bool>,
    /// The columns of [`CaseView::runs`].
    pub run_header: Vec<String>,
    /// One row per run (HTML-escaped cells).
    pub runs: Vec<Vec<String>>,
}

impl CaseView {
    fn label(&self) -> String {
        let m = if self.method.is_empty() { String::new() } else { format!("{} · ", self.method) };
        format!("{m}{} {} τ {:.1}", self.scenario, self.style, self.tau_s)
    }

    fn anchor(&self) -> String {
        format!("case-{}", self.label())
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect::<String>()
            + &format!(
                "-{}",
                self.vut.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '-' }).collect::<String>()
            )
    }
}

/// The distinct values of `key` over `cases`, in order of first appearance.
fn distinct(cases: &[CaseView], key: impl Fn(&CaseView) -> &String) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for c in cases {
        if !out.contains(key(c)) {
            out.push(key(c).clone());
        }
    }
    out
}

/// The VUTs of `cases` in order of first appearance.
fn vuts(cases: &[CaseView]) -> Vec<String> {
    distinct(cases, |c| &c.vut)
}

/// The methods (or settings) of `cases` in order of first appearance.
fn methods(cases: &[CaseView]) -> Vec<String> {
    distinct(cases, |c| &c.method)
}

/// The experiment's printed markdown (tables, paragraphs, headings) as HTML.
pub fn markdown(md: &str) -> String {
    let mut h = String::new();
    let mut rows: Vec<Vec<String>> = Vec::new();
    let flush = |h: &mut String, rows: &mut Vec<Vec<String>>| {
        if rows.is_empty() {
            return;
        }
        let header: Vec<String> = rows.remove(0);
        let body: Vec<Vec<String>> =
            rows.drain(..).filter(|r| !r.iter().all(|c| c.chars().all(|ch| matches!(ch, '-' | ':' | ' ')))).collect();
        let header: Vec<&str> = header.iter().map(String::as_str).collect();
        h.push_str("<div class=\"scroll\">");
        h.push_str(&table("md", &header, &body));
        h.push_str("</div>");
    };
    let mut list = false;
    for line in md.lines() {
        let t = line.trim();
        if t.starts_with('|') {
            let cells: Vec<String> = t.trim_matches('|').split('|').map(|c| inline(c.trim())).collect();
            rows.push(cells);
            continue;
        }
        flush(&mut h, &mut rows);
        if let Some(item) = t.strip_prefix("- ") {
            if !list {
                h.push_str("<ul>");
                list = true;
            }
            let _ = write!(h, "<li>{}</li>", inline(item));
            continue;
        }
        if list {
            h.push_str("</ul>");
            list = false;
        }
        if t.is_empty() {
            continue;
        }
        if let Some(rest) = t.strip_prefix("### ") {
            let _ = write!(h, "<h4>{}</h4>", inline(rest));
        } else if let Some(rest) = t.strip_prefix("## ") {
            let _ = write!(h, "<h3>{}</h3>", inline(rest));
        } else if let Some(rest) = t.strip_prefix("# ") {
            let _ = write!(h, "<h3>{}</h3>", inline(rest));
        } else {
            let _ = write!(h, "<p>{}</p>", inline(t));
        }
    }
    flush(&mut h, &mut rows);
    if list {
        h.push_str("</ul>");
    }
    h
}

/// Inline markdown: `**bold**` and `` `code` ``, the rest escaped.
fn inline(s: &str) -> String {
    let e = esc(s);
    let mut out = String::new();
    let mut bold = false;
    let mut code = false;
    let mut chars = e.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '*' && chars.peek() == Some(&'*') {
            chars.next();
            out.push_str(if bold { "</b>" } else { "<b>" });
            bold = !bold;
        } else if c == '`' {
            out.push_str(if code { "</code>" } else { "<code>" });
            code = !code;
        } else {
            out.push(c);
        }
    }
    if bold {
        out.push_str("</b>");
    }
    if code {
        out.push_str("</code>");
    }
    out
}

/// Every run's PET as a strip per case, τ in red, one plot per VUT; cases whose τ the VUT does
/// not allow are shaded and labelled.
pub fn strips(cases: &[CaseView]) -> String {
    let mut h = String::from(
        "<h2>Every run's PET, per VUT</h2><p class=\"muted\">One dot per run (PET<sub>min</sub>), the box from the first to the third quartile with the median, τ as a red line; a shaded column is a target this VUT does not allow (measured by the open-loop reach grid).</p><div class=\"grid2\">",
    );
    let many_methods = methods(cases).len() > 1;
    for vut in vuts(cases) {
        let strips: Vec<Strip> = cases
            .iter()
            .filter(|c| c.vut == vut)
            .map(|c| Strip {
                label: if many_methods {
                    format!("{}\n{} {:.1}", short(&c.method), &c.style.chars().take(1).collect::<String>(), c.tau_s)
                } else {
                    format!("{} {}\n{:.1} s", short(&c.scenario), c.style, c.tau_s)
                },
                values: c.pets_s.clone(),
                colour: colour(methods(cases).iter().position(|m| *m == c.method).unwrap_or(0)),
                reference: Some(c.tau_s),
                unreachable: c.reachable == Some(false),
            })
            .collect();
        let plot = StripPlot { title: format!("PET per run — VUT {vut}"), y_label: "PET_min (s)".into(), strips };
        let _ = write!(h, "<div class=\"scroll\">{}</div>", plot.svg("strips"));
    }
    h.push_str("</div>");
    h
}

fn short(s: &str) -> String {
    let s: String = s.chars().take(12).collect();
    s
}

/// The steering error of every case against τ, one plot per VUT, a series per method (or style).
pub fn error_vs_tau(cases: &[CaseView]) -> String {
    let mut h = String::from("<h2>Steering error against τ, per VUT</h2><div class=\"grid2\">");
    let ms = methods(cases);
    for vut in vuts(cases) {
        let mut series: Vec<Series> = Vec::new();
        let keys: Vec<(String, String)> = if ms.len() > 1 {
            ms.iter().map(|m| (m.clone(), String::new())).collect()
        } else {
            vec![
                (ms.first().cloned().unwrap_or_default(), "rush".into()),
                (ms.first().cloned().unwrap_or_default(), "yield".into()),
            ]
        };
        for (i, (m, style)) in keys.iter().enumerate() {
            let pts: Vec<(f64, f64)> = cases
                .iter()
                .filter(|c| c.vut == vut && c.method == *m && (style.is_empty() || c.style == *style))
                .filter_map(|c| Some((c.tau_s, 100.0 * c.error_rel?)))
                .collect();
            if pts.is_empty() {
                continue;
            }
            let name = match (m.is_empty(), style.is_empty()) {
                (true, _) => style.clone(),
                (false, true) => m.clone(),
                (false, false) => format!("{m} {style}"),
            };
            series.push(Series::line(name, pts, colour(i)));
        }
        let plot = LinePlot {
            title: format!("Steering error — VUT {vut}"),
            x_label: "target τ (s)".into(),
            y_label: "|mean PET − τ| / τ (%)".into(),
            series,
            levels: vec![Level { y: 10.0, label: "10 %".into() }],
            y_range: None,
            x_range: None,
            cursor: false,
            markers: true,
        };
        h.push_str(&plot.svg("error"));
    }
    h.push_str("</div>");
    h
}

/// The methods side by side: per VUT and method, the mean error, the runs, collisions and the
/// order; only when the experiment compares methods.
pub fn methods_side_by_side(cases: &[CaseView]) -> String {
    let ms = methods(cases);
    if ms.len() < 2 {
        return String::new();
    }
    let mut header = vec!["VUT".to_owned()];
    header.extend(ms.iter().map(|m| esc(m)));
    let mut rows = Vec::new();
    for vut in vuts(cases) {
        let mut row = vec![esc(&vut)];
        for m in &ms {
            let own: Vec<&CaseView> = cases.iter().filter(|c| c.vut == vut && c.method == *m).collect();
            let errs: Vec<f64> = own.iter().filter_map(|c| c.error_rel).collect();
            let runs: usize = own.iter().map(|c| c.pets_s.len() + c.unmeasured).sum();
            let coll: usize = own.iter().map(|c| c.collisions).sum();
            let mean = (!errs.is_empty()).then(|| errs.iter().sum::<f64>() / errs.len() as f64);
            row.push(format!(
                "{} mean error<br><span class=\"muted\">{} case{}, {runs} runs</span><br>{}",
                pct(mean),
                own.len(),
                if own.len() == 1 { "" } else { "s" },
                if coll > 0 { format!("<span class=\"warn\">{coll} collisions</span>") } else { "no collision".into() }
            ));
        }
        rows.push(row);
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    format!("<h2>The methods side by side</h2><div class=\"scroll\">{}</div>", table("methods", &header, &rows))
}

/// Each case's runs, folded: the case's figures in the summary line, every run in the table.
pub fn drill_down(cases: &[CaseView]) -> String {
    let mut h = String::from("<h2>Runs, case by case</h2>");
    for vut in vuts(cases) {
        let _ = write!(h, "<h3>VUT {}</h3>", esc(&vut));
        for c in cases.iter().filter(|c| c.vut == vut) {
            let mean = (!c.pets_s.is_empty()).then(|| c.pets_s.iter().sum::<f64>() / c.pets_s.len() as f64);
            let _ = write!(
                h,
                "<details id=\"{}\"><summary>{} — mean PET {} s, error {}, {} runs{}{}{}</summary>",
                esc(&c.anchor()),
                esc(&c.label()),
                num(mean, 2),
                pct(c.error_rel),
                c.pets_s.len() + c.unmeasured,
                if c.unmeasured > 0 { format!(", {} without PET", c.unmeasured) } else { String::new() },
                if c.collisions > 0 {
                    format!(", <span class=\"warn\">{} collisions</span>", c.collisions)
                } else {
                    String::new()
                },
                if c.reachable == Some(false) {
                    ", <span class=\"warn\">τ not allowed by this VUT</span>"
                } else {
                    ""
                }
            );
            if c.runs.is_empty() {
                h.push_str("<p class=\"muted\">This experiment keeps the case's figures, not its single runs.</p>");
            } else {
                let header: Vec<&str> = c.run_header.iter().map(String::as_str).collect();
                h.push_str(&table("runs", &header, &c.runs));
            }
            h.push_str("</details>");
        }
    }
    h
}

/// What an experiment hands its report: its cases, each with its runs, and any section of its own.
/// Each experiment implements it beside its own types, so the report knows none of them.
pub trait ExperimentView {
    /// Every case with its runs.
    fn case_views(&self) -> Vec<CaseView>;

    /// A section of the experiment's own before the usual body (a campaign's learning); none by
    /// default.
    fn lead(&self) -> String {
        String::new()
    }
}

/// The usual body: the experiment's own section, the tables, strips, error against τ, methods,
/// drill-down.
pub fn body(markdown_tables: &str, view: &dyn ExperimentView) -> String {
    let cases = view.case_views();
    let mut h = view.lead();
    h.push_str("<h2>Results</h2>");
    h.push_str(&markdown(markdown_tables));
    h.push_str(&strips(&cases));
    h.push_str(&error_vs_tau(&cases));
    h.push_str(&methods_side_by_side(&cases));
    h.push_str(&drill_down(&cases));
    h
}

impl CaseView {
    /// A case of figures over repeated runs, with the PETs as the only per-run detail.
    pub fn of_stats(
        scenario: &str,
        vut: &str,
        method: String,
        style: v2t_model::Style,
        tau_s: f64,
        stats: &crate::stats::RunStats,
    ) -> Self {
        Self {
            scenario: scenario.to_owned(),
            vut: vut.to_owned(),
            method,
            style: style.to_string(),
            tau_s,
            pets_s: stats.pets_s.clone(),
            unmeasured: stats.unmeasured,
            collisions: stats.collisions,
            error_rel: stats.error_rel(tau_s),
            reachable: None,
            run_header: vec!["measured run".into(), "PET<sub>min</sub> (s)".into(), "PET − τ (s)".into()],
            runs: stats
                .pets_s
                .iter()
                .enumerate()
                .map(|(k, p)| vec![(k + 1).to_string(), format!("{p:.2}"), format!("{:+.2}", p - tau_s)])
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn case(vut: &str, method: &str, tau: f64, pets: &[f64]) -> CaseView {
        CaseView {
            scenario: "left_turn".into(),
            vut: vut.into(),
            method: method.into(),
            style: "rush".into(),
            tau_s: tau,
            pets_s: pets.to_vec(),
            error_rel: Some(0.05),
            reachable: Some(tau > 1.6),
            run_header: vec!["seed".into(), "PET (s)".into()],
            runs: pets.iter().enumerate().map(|(k, p)| vec![k.to_string(), format!("{p:.2}")]).collect(),
            ..CaseView::default()
        }
    }

    #[test]
    fn markdown_tables_become_html_tables_and_text_is_escaped() {
        let h = markdown("# Title\nsome <text> with **bold**\n\n| a | b |\n|---|--:|\n| 1 | `x` |\n- one\n- two\nend");
        assert!(h.contains("<h3>Title</h3>") && h.contains("&lt;text&gt;") && h.contains("<b>bold</b>"), "{h}");
        assert!(h.contains("<th>a</th><th>b</th>") && h.contains("<td>1</td><td><code>x</code></td>"), "{h}");
        assert!(!h.contains("---"), "the separator row is no row: {h}");
        assert!(h.contains("<ul><li>one</li><li>two</li></ul><p>end</p>"), "{h}");
    }

    #[test]
    fn every_vut_gets_its_own_plots_and_an_unreachable_target_is_marked() {
        let cases = vec![case("idm-normal", "", 1.5, &[1.4, 1.6]), case("idm-cautious", "", 3.0, &[2.9])];
        let h = strips(&cases);
        assert_eq!(h.matches("<svg class=\"plot strip").count(), 2, "one strip plot per VUT");
        assert!(h.contains("not allowed"), "τ 1.5 is marked as not allowed: {h}");
        assert_eq!(error_vs_tau(&cases).matches("<svg").count(), 2);
        let d = drill_down(&cases);
        assert_eq!(d.matches("<details").count(), 2);
        assert!(d.contains("<td>1.60</td>"));
        assert!(methods_side_by_side(&cases).is_empty(), "one method: nothing side by side");
        let two = vec![case("m", "Video2Track", 2.0, &[2.0]), case("m", "Diffusion-only", 2.0, &[3.0])];
        assert!(methods_side_by_side(&two).contains("<th>Diffusion-only</th>"));
    }
}
