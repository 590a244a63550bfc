//! The demo's HTML report: the results table, and per scenario the routes and driven paths on
//! the map and the predicted PET over time. Self-contained (inline SVG, nothing fetched).

use std::fmt::Write as _;

use serde_json::Value;

use super::{Summary, at};

pub(super) fn html(summary: &Summary, runs: &[(Value, v2t_model::grounded::GroundedScenario)]) -> String {
    let mut h = String::from(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>Video2Track demo</title><style>\
         body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}th{background:#f4f4f4}\
         .row{display:flex;gap:1em;flex-wrap:wrap}svg{border:1px solid #ddd;background:#fafafa}</style></head><body>\
         <h1>Video2Track demo</h1>",
    );
    let _ = write!(
        h,
        "<p>Semantics replayed from the shipped hand-written cassettes, grounded on the proving ground, prior: {}; \
         each run closes the loop through the BV's onboard processes (iceoryx2) and the simulated proving ground. \
         Wall time {:.1} s.</p><table><tr><th>scenario</th><th>style</th><th>PET video (s)</th><th>PET<sup>min</sup> track (s)</th>\
         <th>fidelity error</th><th>order</th><th>collision</th><th>min distance (m)</th>\
         <th>BV class</th><th>BV W<sub>1</sub> accel (m/s²)</th><th>BV W<sub>1</sub> jerk (m/s³)</th></tr>",
        esc(&summary.prior),
        summary.wall_s
    );
    for s in &summary.scenarios {
        let _ = write!(
            h,
            "<tr><td style=\"text-align:left\">{}</td><td>{}</td><td>{:.2}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>{}</tr>",
            esc(&s.name),
            esc(&s.style),
            s.pet_video_s,
            s.pet_min_track_s.map_or_else(|| "–".into(), |p| format!("{p:.2}")),
            s.fidelity_error_rel.map_or_else(|| "–".into(), |f| format!("{:.1} %", 100.0 * f)),
            match s.order_ok {
                Some(true) => "as asked",
                Some(false) => "wrong",
                None => "–",
            },
            if s.collision { "yes" } else { "no" },
            s.min_distance_m.map_or_else(|| "–".into(), |d| format!("{d:.2}")),
            realism_cells(s.bv_realism.as_ref())
        );
    }
    h.push_str("</table><p>BV realism: W<sub>1</sub> distances of the BV's longitudinal acceleration and jerk to recorded human driving (NGSIM) of its manoeuvre class; a class without human recordings says so.</p>");
    for (s, (run, grounded)) in summary.scenarios.iter().zip(runs) {
        let _ = write!(
            h,
            "<h2>{}</h2><div class=\"row\">{}{}</div>",
            esc(&s.name),
            map_svg(run, grounded),
            pet_svg(run, s.pet_video_s)
        );
    }
    h.push_str("</body></html>\n");
    h
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

const COLORS: [&str; 3] = ["#1f6fd1", "#d2461c", "#2a9d4b"];

/// Routes (grey) and driven paths (colour) in the track frame, north up.
fn map_svg(run: &Value, grounded: &v2t_model::grounded::GroundedScenario) -> String {
    let ids: Vec<&str> =
        at(run, "/agent_ids").as_array().map(|a| a.iter().filter_map(Value::as_str).collect()).unwrap_or_default();
    let trace = at(run, "/trace").as_array().cloned().unwrap_or_default();
    let mut paths: Vec<Vec<(f64, f64)>> = vec![Vec::new(); ids.len()];
    for sample in &trace {
        for (i, a) in at(sample, "/agents").as_array().into_iter().flatten().enumerate() {
            if let (Some(p), Some(x), Some(y)) =
                (paths.get_mut(i), at(a, "/state/px").as_f64(), at(a, "/state/py").as_f64())
            {
                p.push((x, y));
            }
        }
    }
    let routes: Vec<Vec<(f64, f64)>> =
        grounded.agents.iter().map(|a| a.route.iter().map(|p| (p.x, p.y)).collect()).collect();
    let all = paths.iter().chain(&routes).flatten();
    let (mut x0, mut y0, mut x1, mut y1) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (x, y) in all {
        x0 = x0.min(*x);
        y0 = y0.min(*y);
        x1 = x1.max(*x);
        y1 = y1.max(*y);
    }
    if !x0.is_finite() {
        return String::new();
    }
    let (w, hgt) = (480.0, 480.0);
    let span = (x1 - x0).max(y1 - y0).max(1.0) + 20.0;
    let scale = w / span;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let tx = |x: f64| w / 2.0 + (x - cx) * scale;
    let ty = |y: f64| hgt / 2.0 - (y - cy) * scale;
    let poly = |pts: &[(f64, f64)]| {
        pts.iter().map(|(x, y)| format!("{:.1},{:.1}", tx(*x), ty(*y))).collect::<Vec<_>>().join(" ")
    };
    let mut s =
        format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{hgt}\" viewBox=\"0 0 {w} {hgt}\">");
    for r in &routes {
        let _ = write!(
            s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"#bbb\" stroke-width=\"{:.1}\" stroke-linecap=\"round\"/>",
            poly(r),
            3.5 * scale
        );
    }
    for (i, p) in paths.iter().enumerate() {
        let c = COLORS.get(i % COLORS.len()).copied().unwrap_or("#000");
        let _ = write!(s, "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"2\"/>", poly(p));
        if let (Some((x, y)), Some(id)) = (p.first(), ids.get(i)) {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"{c}\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"12\" fill=\"{c}\">{}</text>",
                tx(*x),
                ty(*y),
                tx(*x) + 6.0,
                ty(*y) - 6.0,
                esc(id)
            );
        }
    }
    for c in &grounded.conflicts {
        let _ = write!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"6\" fill=\"none\" stroke=\"#c00\" stroke-width=\"2\"><title>conflict {}</title></circle>",
            tx(c.point.x),
            ty(c.point.y),
            esc(&c.anchor_id)
        );
    }
    let _ = write!(
        s,
        "<text x=\"8\" y=\"{:.0}\" font-size=\"11\" fill=\"#666\">grey: grounded routes; colour: driven; red: conflict; {:.0} m across</text></svg>",
        hgt - 8.0,
        span
    );
    s
}

/// Predicted PET over time with τ.
fn pet_svg(run: &Value, tau: f64) -> String {
    let trace = at(run, "/trace").as_array().cloned().unwrap_or_default();
    let pts: Vec<(f64, f64)> = trace
        .iter()
        .filter_map(|s| Some((at(s, "/t_s").as_f64()?, at(s, "/predicted_pet_s").as_array()?.first()?.as_f64()?)))
        .collect();
    let t_end = trace.last().and_then(|s| at(s, "/t_s").as_f64()).unwrap_or(1.0).max(1.0);
    let (w, hgt, pad) = (560.0, 300.0, 40.0);
    let y_max = pts.iter().map(|p| p.1).fold(tau * 2.0, f64::max).clamp(1.0, 15.0);
    let tx = |t: f64| pad + t / t_end * (w - 2.0 * pad);
    let ty = |v: f64| hgt - pad - v.clamp(0.0, y_max) / y_max * (hgt - 2.0 * pad);
    let mut s =
        format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{hgt}\" viewBox=\"0 0 {w} {hgt}\">");
    let _ = write!(
        s,
        "<line x1=\"{pad}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#999\"/><line x1=\"{pad}\" y1=\"{pad}\" x2=\"{pad}\" y2=\"{:.1}\" stroke=\"#999\"/>",
        hgt - pad,
        w - pad,
        hgt - pad,
        hgt - pad
    );
    let _ = write!(
        s,
        "<line x1=\"{pad}\" y1=\"{0:.1}\" x2=\"{1:.1}\" y2=\"{0:.1}\" stroke=\"#c00\" stroke-dasharray=\"6 4\"/><text x=\"{2:.1}\" y=\"{3:.1}\" font-size=\"11\" fill=\"#c00\">τ = {tau:.2} s</text>",
        ty(tau),
        w - pad,
        w - pad - 60.0,
        ty(tau) - 4.0
    );
    let line = pts.iter().map(|(t, v)| format!("{:.1},{:.1}", tx(*t), ty(*v))).collect::<Vec<_>>().join(" ");
    let _ = write!(s, "<polyline points=\"{line}\" fill=\"none\" stroke=\"#1f6fd1\" stroke-width=\"2\"/>");
    let _ = write!(
        s,
        "<text x=\"{pad}\" y=\"16\" font-size=\"12\">predicted PET (s) over time (0–{t_end:.0} s); axis top {y_max:.1} s</text></svg>"
    );
    s
}

/// The BV-realism cells of a row: class, W₁ of acceleration and of jerk.
fn realism_cells(r: Option<&serde_json::Value>) -> String {
    let Some(r) = r else { return "<td>–</td><td>–</td><td>–</td>".into() };
    let class = esc(r.pointer("/class").and_then(serde_json::Value::as_str).unwrap_or("–"));
    let num = |k: &str| r.pointer(k).and_then(serde_json::Value::as_f64);
    match (num("/realism/w1_accel_mps2"), num("/realism/w1_jerk_mps3")) {
        (Some(a), Some(j)) => format!("<td>{class}</td><td>{a:.3}</td><td>{j:.3}</td>"),
        _ => format!("<td>{class}</td><td colspan=\"2\">no human reference</td>"),
    }
}
