//! One run in the report, from its run file ([`RunFile`], which `video2track sim --json` and
//! `v2t-sim-ecu --out` write): the map, the routes and driven paths, the conflict zones, footprints
//! at the key moments and a time slider that moves them, plots over time, the zone-occupancy
//! timeline, the regulator's status, the gate's state, the realism and links to the run's files.
//!
//! A part the file does not hold (no layout in a file written before runs kept it, no regulator in
//! a run whose BVs follow their references, no gate outside the onboard runtime, no realism
//! without a human reference) is said, not drawn.

use std::fmt::Write as _;

use serde_json::Value;
use v2t_map::svg::{View, Window, path_d};
use v2t_model::geometry::Point2;
use v2t_model::metrics::{Passage, PetOutcome};
use v2t_sim::runfile::RunFile;
use v2t_sim::runner::ConflictResult;

use super::plot::{Bar, Level, LinePlot, Series, Timeline, colour};
use super::{esc, num, table};

/// What a run's section is made of.
#[derive(Debug, Clone)]
pub struct RunInput<'a> {
    /// The section's anchor (letters, digits, `-`, `_`).
    pub id: String,
    /// Heading.
    pub title: String,
    /// The run file, read.
    pub run: &'a RunFile,
    /// The track's map, drawn under the run; `None`: the run's own routes only.
    pub map: Option<&'a v2t_map::Map>,
    /// What the drawing's ground is (the map file, or the card's own geometry).
    pub ground: String,
    /// Links to the run's files: label and relative address.
    pub links: Vec<(String, String)>,
    /// Extra facts for the table (label, value; HTML-escaped by the caller).
    pub facts: Vec<(String, String)>,
}

/// A footprint the file does not give (no layout), m: length and width.
const DEFAULT_FOOTPRINT_M: (f64, f64) = (4.6, 1.8);

/// Samples the JavaScript gets: at most this many per run (the trace is thinned evenly).
const MAX_SAMPLES: usize = 800;

/// A vehicle's recorded motion, thinned.
struct Track {
    id: String,
    length_m: f64,
    width_m: f64,
    x: Vec<f64>,
    y: Vec<f64>,
    h: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    a_req: Vec<f64>,
}

struct Trace {
    t: Vec<f64>,
    tracks: Vec<Track>,
    /// Predicted PET per conflict and sample.
    pet: Vec<Vec<Option<f64>>>,
}

fn read_trace(run: &RunFile) -> Trace {
    let stride = run.trace.len().div_ceil(MAX_SAMPLES).max(1);
    let kept: Vec<_> = run.trace.iter().step_by(stride).collect();
    let dims = run.layout.as_ref().map(|l| l.dims.as_slice()).unwrap_or_default();
    let mut tracks: Vec<Track> = run
        .agent_ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let d = dims.get(i).map_or(DEFAULT_FOOTPRINT_M, |d| (d.length_m, d.width_m));
            Track {
                id: id.clone(),
                length_m: d.0,
                width_m: d.1,
                x: Vec::with_capacity(kept.len()),
                y: Vec::with_capacity(kept.len()),
                h: Vec::with_capacity(kept.len()),
                v: Vec::with_capacity(kept.len()),
                a: Vec::with_capacity(kept.len()),
                a_req: Vec::with_capacity(kept.len()),
            }
        })
        .collect();
    let mut t = Vec::with_capacity(kept.len());
    let mut pet = vec![Vec::with_capacity(kept.len()); run.result.conflicts.len()];
    for s in kept {
        t.push(s.t_s);
        for (i, tr) in tracks.iter_mut().enumerate() {
            // A sample without this vehicle breaks its lines there.
            let a = s.agents.get(i);
            tr.x.push(a.map_or(f64::NAN, |a| a.state.px));
            tr.y.push(a.map_or(f64::NAN, |a| a.state.py));
            tr.h.push(a.map_or(0.0, |a| a.state.theta_rad));
            tr.v.push(a.map_or(f64::NAN, |a| a.state.speed_mps));
            tr.a.push(a.map_or(f64::NAN, |a| a.accel_mps2));
            tr.a_req.push(a.map_or(f64::NAN, |a| a.request.accel_mps2));
        }
        for (k, p) in pet.iter_mut().enumerate() {
            p.push(s.predicted_pet_s.get(k).copied().flatten());
        }
    }
    Trace { t, tracks, pet }
}

/// A moment worth a footprint and a button.
#[derive(Debug, Clone)]
struct Moment {
    t_s: f64,
    label: String,
}

/// The moments: zone entries and exits, the closest approach, a collision.
fn moments(run: &RunFile) -> Vec<Moment> {
    let r = &run.result;
    let mut m = Vec::new();
    for c in &r.conflicts {
        for (p, who) in [(c.vut_passage, "VUT"), (c.bv_passage, c.bv_id.as_str())] {
            if let Some(Passage { enter_t_s, exit_t_s }) = p {
                m.push(Moment { t_s: enter_t_s, label: format!("{who} enters the zone") });
                if let Some(x) = exit_t_s {
                    m.push(Moment { t_s: x, label: format!("{who} leaves the zone") });
                }
            }
        }
    }
    // With fewer than two vehicles there is no closest approach.
    if r.min_distance_m.is_finite() {
        m.push(Moment { t_s: r.min_distance_t_s, label: "closest approach".into() });
    }
    if let Some(c) = &r.collision {
        m.push(Moment { t_s: c.t_s, label: "collision".into() });
    }
    m.retain(|x| x.t_s.is_finite());
    m.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    m
}

/// The moment PET_min was realised: the second vehicle's entry into the zone with the smallest
/// measured PET (the end of the gap PET measures).
fn pet_min_moment(run: &RunFile) -> Option<(f64, f64)> {
    run.result
        .conflicts
        .iter()
        .filter_map(|c| {
            let pet = c.pet.pet_s()?;
            let (v, b) = (c.vut_passage?.enter_t_s, c.bv_passage?.enter_t_s);
            Some((v.max(b), pet))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

fn index_at(t: &[f64], time: f64) -> usize {
    let mut best = 0;
    for (k, v) in t.iter().enumerate() {
        if (v - time).abs() < (t.get(best).copied().unwrap_or(f64::INFINITY) - time).abs() {
            best = k;
        }
    }
    best
}

/// The section of one run.
pub fn section(input: &RunInput<'_>) -> String {
    let run = input.run;
    let trace = read_trace(run);
    let t_range = (
        trace.t.first().copied().filter(|v| v.is_finite()).unwrap_or(0.0),
        trace.t.last().copied().filter(|v| v.is_finite()).unwrap_or(1.0),
    );
    let moments = moments(run);
    let pet_min = pet_min_moment(run);
    let mut h = String::new();
    let _ = write!(h, "<section class=\"run\" id=\"{}\"><h2>{}</h2>", esc(&input.id), esc(&input.title));
    h.push_str(&facts(input));
    // The map and the slider.
    let _ = write!(
        h,
        "<div class=\"controls\"><input type=\"range\" class=\"slider\" min=\"0\" max=\"{}\" value=\"0\" aria-label=\"time\">",
        trace.t.len().saturating_sub(1)
    );
    if let Some((t, pet)) = pet_min {
        let _ = write!(h, "<button data-t=\"{t:.3}\">PET<sub>min</sub> {pet:.2} s realised ({t:.2} s)</button>");
    }
    for m in &moments {
        let _ = write!(h, "<button data-t=\"{:.3}\">{} ({:.2} s)</button>", m.t_s, esc(&m.label), m.t_s);
    }
    h.push_str("<span class=\"readout\"></span></div><div class=\"grid2\">");
    let _ = write!(
        h,
        "<figure class=\"mapfig\">{}<figcaption class=\"muted\">North up. Dashed grey: routes; colour: driven paths; red bands: \
         each vehicle's stretch in the conflict zone (where they cross is the zone); outlines: both vehicles at every \
         zone entry and exit and when PET<sub>min</sub> was realised; filled: at the slider's time.{}</figcaption></figure>",
        map_svg(input, &trace, &moments, pet_min),
        if run.layout.is_none() {
            " This run file has no layout (it was written before runs kept one): no routes or conflict zones are \
             drawn, and the footprints are 4.6 × 1.8 m."
        } else {
            ""
        }
    );
    h.push_str("<div class=\"col\">");
    h.push_str(&occupancy(run, t_range));
    h.push_str(&states(run, t_range));
    h.push_str("</div></div><div class=\"grid2\">");
    h.push_str(&plots(run, &trace, t_range));
    h.push_str("</div>");
    h.push_str(&realism(run));
    if !input.links.is_empty() {
        h.push_str("<p class=\"links\">Files: ");
        for (label, href) in &input.links {
            let _ = write!(h, "<a href=\"{}\">{}</a>", esc(href), esc(label));
        }
        h.push_str("</p>");
    }
    // The data the slider moves the footprints with.
    let start = pet_min.map(|p| p.0).or_else(|| moments.first().map(|m| m.t_s));
    let _ =
        write!(h, "<script type=\"application/json\" class=\"rundata\">{}</script></section>", rundata(&trace, start));
    h
}

fn rundata(trace: &Trace, start: Option<f64>) -> String {
    let r = |v: &[f64], d: i32| -> Value {
        let k = 10f64.powi(d);
        Value::Array(
            v.iter()
                .map(|x| if x.is_finite() { serde_json::json!((x * k).round() / k) } else { Value::Null })
                .collect(),
        )
    };
    let agents: Vec<Value> = trace
        .tracks
        .iter()
        .map(|tr| serde_json::json!({"id": tr.id, "x": r(&tr.x, 2), "y": r(&tr.y, 2), "h": r(&tr.h, 3), "v": r(&tr.v, 2)}))
        .collect();
    let pet: Vec<Option<f64>> = trace.pet.first().cloned().unwrap_or_default();
    let pet: Vec<f64> = pet.iter().map(|p| p.unwrap_or(f64::NAN)).collect();
    let mut doc = serde_json::json!({"t": r(&trace.t, 3), "agents": agents, "pet": r(&pet, 2)});
    if let (Some(s), Some(obj)) = (start, doc.as_object_mut()) {
        obj.insert("start".into(), serde_json::json!(s));
    }
    // `</` cannot end the script element early: the JSON holds no such pair, but ids could.
    doc.to_string().replace("</", "<\\/")
}

fn facts(input: &RunInput<'_>) -> String {
    let r = &input.run.result;
    let tau = r.target.tau_s();
    let err = r.pet_min_s.map(|p| (p - tau).abs() / tau);
    let order = r
        .conflicts
        .iter()
        .map(|c| match c.order_matches_style {
            Some(true) => "<span class=\"ok\">as the style asks</span>",
            Some(false) => "<span class=\"warn\">opposite to the style</span>",
            None => "no order",
        })
        .collect::<Vec<_>>()
        .join(", ");
    let collision = match &r.collision {
        None => "none".to_owned(),
        Some(c) => {
            let [a, b] = &c.agents;
            format!("<span class=\"warn\">{} and {} at {:.2} s</span>", esc(a), esc(b), c.t_s)
        }
    };
    let closest = if r.min_distance_m.is_finite() {
        format!("{:.2} m at {:.2} s", r.min_distance_m, r.min_distance_t_s)
    } else {
        "– (fewer than two vehicles)".to_owned()
    };
    let mut rows: Vec<Vec<String>> = vec![
        vec!["scenario".into(), esc(&r.scenario)],
        vec!["VUT driver".into(), esc(&r.vut_model)],
        vec!["BV controller".into(), esc(&r.bv_controller)],
        vec!["seed".into(), r.seed.to_string()],
        vec!["style, target τ".into(), format!("{}, {:.2} s", r.target.style(), r.target.tau_s())],
        vec![
            "PET<sub>min</sub> achieved".into(),
            format!("{} s (error against τ {})", num(r.pet_min_s, 2), super::pct(err)),
        ],
        vec!["order".into(), order],
        vec!["closest approach".into(), closest],
        vec!["smallest TTC".into(), format!("{} s", num(r.min_ttc_s, 2))],
        vec!["collision".into(), collision],
        vec![
            "duration".into(),
            format!("{:.1} s, {}", r.duration_s, if r.completed { "completed" } else { "stopped before the end" }),
        ],
        vec!["drawn on".into(), esc(&input.ground)],
    ];
    if let Some(e) = &input.run.ecu {
        rows.push(vec![
            "CAN frames (simulated ECU)".into(),
            format!(
                "{} accepted, {} rejected; {} steps braked on the ECU's command timeout; {} late steps",
                e.frames_ok, e.frames_rejected, e.timeout_steps, e.late_steps
            ),
        ]);
    }
    rows.extend(input.facts.iter().map(|(k, v)| vec![esc(k), v.clone()]));
    table("facts", &[], &rows)
}

/// The point `s` m along a route sampled every [`v2t_sim::runner::ROUTE_STEP_M`].
fn along(route: &[[f64; 2]], s: f64) -> Option<(f64, f64)> {
    let step = v2t_sim::runner::ROUTE_STEP_M;
    let k = (s / step).floor().max(0.0) as usize;
    let a = route.get(k).or_else(|| route.last())?;
    let b = route.get(k.saturating_add(1)).unwrap_or(a);
    let u = (s / step - k as f64).clamp(0.0, 1.0);
    Some((a[0] + (b[0] - a[0]) * u, a[1] + (b[1] - a[1]) * u))
}

/// Every vehicle's route (none without a layout).
fn routes(run: &RunFile) -> &[Vec<[f64; 2]>] {
    run.layout.as_ref().map(|l| l.routes.as_slice()).unwrap_or_default()
}

/// The map's window: every route and driven position with a margin, not thinner than 2:3 either
/// way (so that a straight road still shows its surroundings); `None` without a position.
fn map_window(trace: &Trace, routes: &[Vec<[f64; 2]>]) -> Option<Window> {
    let driven = trace.tracks.iter().flat_map(|t| t.x.iter().zip(&t.y).map(|(x, y)| Point2 { x: *x, y: *y }));
    let planned = routes.iter().flatten().map(|p| Point2 { x: p[0], y: p[1] });
    let w = Window::around(driven.chain(planned))?.grown(12.0);
    let (cx, cy) = ((w.x0 + w.x1) / 2.0, (w.y0 + w.y1) / 2.0);
    let half = w.width().max(w.height()) / 3.0;
    let (x0, x1) = if w.width() < 2.0 * half { (cx - half, cx + half) } else { (w.x0, w.x1) };
    let (y0, y1) = if w.height() < 2.0 * half { (cy - half, cy + half) } else { (w.y0, w.y1) };
    Some(Window { x0, y0, x1, y1 })
}

/// The run on the map: the track's lanes and marks (or, without a map, the routes as lanes), the
/// conflict zones, routes and driven paths, fixed footprints at the moments that matter, the
/// footprints the slider moves, the vehicles' names at their starts and a scale bar.
fn map_svg(input: &RunInput<'_>, trace: &Trace, moments: &[Moment], pet_min: Option<(f64, f64)>) -> String {
    let routes = routes(input.run);
    let Some(window) = map_window(trace, routes) else {
        return "<p class=\"muted\">No positions in this run file: no map drawn.</p>".into();
    };
    let view = View { window, px_per_m: (560.0 / window.width()).min(560.0 / window.height()) };
    let mut s = view.open("", &format!("{} — map, routes, driven paths and footprints", input.title), false);
    match input.map {
        Some(map) => s.push_str(&v2t_map::svg::lanes(map, Some(&window.grown(20.0)))),
        // No map: the routes as lanes, so that the drawing still shows the roads driven.
        None => {
            for r in routes {
                let _ = write!(
                    s,
                    "<path d=\"{}\" fill=\"none\" stroke=\"#c9cdd2\" stroke-width=\"3.5\" stroke-linejoin=\"round\"/>",
                    path_d(r.iter().map(|p| (p[0], p[1])))
                );
            }
        }
    }
    zones(&mut s, input.run, routes, trace);
    for r in routes {
        let _ = write!(s, "<path class=\"route\" d=\"{}\"/>", path_d(r.iter().map(|p| (p[0], p[1]))));
    }
    for (i, tr) in trace.tracks.iter().enumerate() {
        let _ = write!(
            s,
            "<path class=\"driven\" stroke=\"{}\" d=\"{}\"><title>{} driven</title></path>",
            colour(i),
            path_d(tr.x.iter().copied().zip(tr.y.iter().copied())),
            esc(&tr.id)
        );
    }
    ghosts(&mut s, trace, moments, pet_min);
    footprints(&mut s, trace);
    s.push_str(View::UPRIGHT);
    // The names at the starts, upright.
    for (i, tr) in trace.tracks.iter().enumerate() {
        if let (Some(x), Some(y)) = (tr.x.first(), tr.y.first())
            && x.is_finite()
            && y.is_finite()
        {
            let _ = write!(
                s,
                "<text x=\"{:.2}\" y=\"{:.2}\" fill=\"{}\" font-size=\"{:.3}\">{} start</text>",
                x + 1.5,
                -y - 1.5,
                colour(i),
                view.m(11.0),
                esc(&tr.id)
            );
        }
    }
    s.push_str(&view.scale_bar());
    s.push_str("</svg>");
    s
}

/// Conflict zones: the stretch of each vehicle's route along which it is in the zone, as wide as
/// the vehicle; where the two bands cross is the zone.
fn zones(s: &mut String, run: &RunFile, routes: &[Vec<[f64; 2]>], trace: &Trace) {
    for z in run.layout.iter().flat_map(|l| &l.zones) {
        for (agent, side) in [(0, z.zone.vut), (z.bv_index.saturating_add(1), z.zone.bv)] {
            let Some(route) = routes.get(agent) else { continue };
            let (a, b) = (side.enter_s_m, side.exit_s_m);
            let width = trace.tracks.get(agent).map_or(DEFAULT_FOOTPRINT_M.1, |t| t.width_m);
            let n = ((b - a) / 0.5).ceil().clamp(1.0, 2000.0) as usize;
            let d = path_d((0..=n).filter_map(|k| along(route, a + (b - a) * k as f64 / n as f64)));
            let _ = write!(
                s,
                "<path class=\"zone\" d=\"{d}\" stroke-width=\"{width:.2}\"><title>conflict zone: {} from {a:.1} to {b:.1} m along its route</title></path>",
                esc(trace.tracks.get(agent).map_or("?", |t| t.id.as_str()))
            );
        }
    }
}

/// Fixed footprints at the zone entries and exits and when PET_min was realised (they stay in
/// print).
fn ghosts(s: &mut String, trace: &Trace, moments: &[Moment], pet_min: Option<(f64, f64)>) {
    let mut fixed: Vec<(f64, String)> =
        moments.iter().filter(|m| m.label.contains("zone")).map(|m| (m.t_s, m.label.clone())).collect();
    if let Some((t, pet)) = pet_min {
        fixed.push((t, format!("PET_min {pet:.2} s realised")));
    }
    for (t, label) in &fixed {
        let k = index_at(&trace.t, *t);
        for (i, tr) in trace.tracks.iter().enumerate() {
            let (Some(x), Some(y), Some(hd)) = (tr.x.get(k), tr.y.get(k), tr.h.get(k)) else { continue };
            if !(x.is_finite() && y.is_finite()) {
                continue;
            }
            let _ = write!(
                s,
                "<rect class=\"ghost\" stroke=\"{}\" x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" transform=\"translate({x:.2} {y:.2}) rotate({:.1})\"><title>{} at {t:.2} s: {}</title></rect>",
                colour(i),
                -tr.length_m / 2.0,
                -tr.width_m / 2.0,
                tr.length_m,
                tr.width_m,
                hd.to_degrees(),
                esc(&tr.id),
                esc(label)
            );
        }
    }
}

/// The footprints the slider moves, at the start.
fn footprints(s: &mut String, trace: &Trace) {
    for (i, tr) in trace.tracks.iter().enumerate() {
        let (l, w) = (tr.length_m, tr.width_m);
        let _ = write!(
            s,
            "<g class=\"fp\" data-agent=\"{i}\" transform=\"translate({:.2} {:.2})\"><rect x=\"{:.2}\" y=\"{:.2}\" width=\"{l:.2}\" height=\"{w:.2}\" fill=\"{}\" fill-opacity=\"0.85\"/>\
             <path d=\"M{:.2} 0 L{:.2} {:.2} L{:.2} {:.2} Z\" fill=\"#fff\"/><title>{}</title></g>",
            tr.x.first().copied().unwrap_or(0.0),
            tr.y.first().copied().unwrap_or(0.0),
            -l / 2.0,
            -w / 2.0,
            colour(i),
            l / 2.0 - 0.2,
            l / 2.0 - 1.2,
            w / 4.0,
            l / 2.0 - 1.2,
            -w / 4.0,
            esc(&tr.id)
        );
    }
}

fn plots(run: &RunFile, trace: &Trace, t_range: (f64, f64)) -> String {
    let mut out = String::new();
    let series = |name: String, t: &[f64], v: &[f64], i: usize, dashed: bool| Series {
        dashed,
        ..Series::line(name, t.iter().copied().zip(v.iter().copied()).collect(), colour(i))
    };
    let mut speed = LinePlot::over_time("Speed", "speed (m/s)", t_range);
    let mut accel = LinePlot::over_time("Acceleration", "acceleration (m/s²)", t_range);
    for (i, tr) in trace.tracks.iter().enumerate() {
        speed.series.push(series(tr.id.clone(), &trace.t, &tr.v, i, false));
        accel.series.push(series(tr.id.clone(), &trace.t, &tr.a, i, false));
        if i > 0 {
            accel.series.push(series(format!("{} requested", tr.id), &trace.t, &tr.a_req, i, true));
        }
    }
    out.push_str(&speed.svg("speed"));
    out.push_str(&accel.svg("accel"));
    // Predicted PET: from the true states at constant velocity, and the regulator's own.
    let tau = run.result.target.tau_s();
    let top = if tau.is_finite() { (3.0 * tau).max(tau + 3.0) } else { 10.0 };
    let clip = |v: Option<f64>| v.filter(|x| x.is_finite() && *x >= 0.0 && *x <= top).unwrap_or(f64::NAN);
    let mut pet = LinePlot::over_time("Predicted PET", "PET (s)", t_range);
    pet.y_range = Some((0.0, top));
    if tau.is_finite() {
        pet.levels.push(Level { y: tau, label: format!("τ = {tau:.2} s") });
    }
    let bv_ids: Vec<&str> = run.result.conflicts.iter().map(|c| c.bv_id.as_str()).collect();
    for (k, p) in trace.pet.iter().enumerate() {
        let v: Vec<f64> = p.iter().map(|x| clip(*x)).collect();
        let who = bv_ids.get(k).copied().unwrap_or("BV");
        pet.series.push(series(format!("constant velocity, {who}"), &trace.t, &v, k + 1, false));
    }
    for (b, plans) in run.regulator.iter().flatten().enumerate() {
        let pts: Vec<(f64, f64)> = plans.iter().map(|p| (p.t_s, clip(p.predicted_pet_s))).collect();
        let who = bv_ids.get(b).copied().unwrap_or("BV");
        pet.series.push(Series { dashed: true, ..Series::line(format!("regulator, {who}"), pts, colour(b + 1)) });
    }
    out.push_str(&pet.svg("pet"));
    out.push_str(&reaction_plot(run, &bv_ids, t_range));
    out
}

/// How each BV's regulator identified the VUT's reaction over the run (its plans'
/// `vut_reacts_p` and `vut_gap_s`, [`v2t_game::reaction`]); empty when no plan carries it.
fn reaction_plot(run: &RunFile, bv_ids: &[&str], t_range: (f64, f64)) -> String {
    let mut plot = LinePlot::over_time(
        "The VUT's reaction to the BV, as the regulator identified it",
        "probability; gap (s)",
        t_range,
    );
    plot.y_range = Some((0.0, 3.5));
    for (b, plans) in run.regulator.iter().flatten().enumerate() {
        if plans.iter().all(|p| p.vut_reacts_p.is_none()) {
            continue;
        }
        let who = bv_ids.get(b).copied().unwrap_or("BV");
        let finite = |v: Option<f64>| v.filter(|x| x.is_finite()).unwrap_or(f64::NAN);
        let p: Vec<(f64, f64)> = plans.iter().map(|q| (q.t_s, finite(q.vut_reacts_p))).collect();
        let gap: Vec<(f64, f64)> = plans.iter().map(|q| (q.t_s, finite(q.vut_gap_s))).collect();
        plot.series.push(Series::line(format!("probability that it reacts, {who}"), p, colour(b + 1)));
        plot.series
            .push(Series { dashed: true, ..Series::line(format!("accepted gap (s), {who}"), gap, colour(b + 1)) });
    }
    if plot.series.is_empty() { String::new() } else { plot.svg("reaction") }
}

fn status_colour(s: &str) -> &'static str {
    match s {
        "Regulating" | "Engaged" => "#009e73",
        "Degraded" => "#e69f00",
        "SafetyYield" => "#cc79a7",
        "Waiting" => "#56b4e9",
        "Passed" | "Disengaged" => "#9a9a9a",
        "Stale" | "Fault" => "#d00000",
        "MinimalRiskStop" => "#d55e00",
        _ => "#333333",
    }
}

/// Bars from a change log `(t, state)` up to `t_end`.
fn bars(log: &[(f64, String)], t_end: f64) -> Vec<Bar> {
    let mut out: Vec<Bar> = Vec::new();
    for (t, state) in log {
        if out.last().is_some_and(|b| b.label == *state) {
            continue;
        }
        if let Some(last) = out.last_mut() {
            last.t1 = *t;
        }
        out.push(Bar { t0: *t, t1: t_end, colour: status_colour(state), label: state.clone() });
    }
    out
}

/// The regulator's status per BV and the actuation gate's state over time.
fn states(run: &RunFile, t_range: (f64, f64)) -> String {
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    match &run.regulator {
        Some(per_bv) => {
            for (b, plans) in per_bv.iter().enumerate() {
                let log: Vec<(f64, String)> = plans.iter().map(|p| (p.t_s, p.status.clone())).collect();
                let id = run.agent_ids.get(b + 1).map_or("BV", String::as_str);
                rows.push((format!("regulator {id}"), bars(&log, t_range.1)));
            }
        }
        None => notes.push(if run.result.bv_controller == "reference" {
            "Regulator: none in this run (the BVs followed their references)."
        } else {
            "Regulator: its decisions are not in this run file."
        }),
    }
    match &run.gate {
        Some(g) => {
            let log: Vec<(f64, String)> = g.iter().map(|r| (r.t_s, r.state.clone())).collect();
            rows.push(("actuation gate".to_owned(), bars(&log, t_range.1)));
        }
        None => notes.push(
            "Actuation gate: none in this world (the in-process simulation has no onboard gateway; runs through \
             v2t-sim-ecu record it).",
        ),
    }
    let mut h = String::new();
    if !rows.is_empty() {
        let mut seen: Vec<&'static str> = Vec::new();
        let mut legend = Vec::new();
        for b in rows.iter().flat_map(|r| r.1.iter()) {
            if !seen.contains(&b.colour) {
                seen.push(b.colour);
                legend.push((b.colour, b.label.clone()));
            }
        }
        h.push_str(
            &Timeline { title: "Regulator status and gate state".into(), rows, t_range, gaps: Vec::new(), legend }
                .svg("states"),
        );
    }
    for n in notes {
        let _ = write!(h, "<p class=\"muted note\">{}</p>", esc(n));
    }
    h
}

/// Who was in each conflict zone when; PET as the gap between the bars.
fn occupancy(run: &RunFile, t_range: (f64, f64)) -> String {
    let conflicts = &run.result.conflicts;
    if conflicts.is_empty() {
        return "<p class=\"muted\">No conflict zone in this run.</p>".into();
    }
    let mut rows = Vec::new();
    let mut gaps = Vec::new();
    for c in conflicts {
        let bv = c.bv_id.as_str();
        let mut ends = Vec::new();
        for (p, who, k) in [(c.vut_passage, "VUT", 0), (c.bv_passage, bv, 1)] {
            let mut row = Vec::new();
            if let Some(Passage { enter_t_s, exit_t_s }) = p {
                row.push(Bar {
                    t0: enter_t_s,
                    t1: exit_t_s.unwrap_or(t_range.1),
                    colour: colour(k),
                    label: format!("{who} in the zone"),
                });
                ends.push((enter_t_s, exit_t_s));
            }
            rows.push((format!("{who} (zone {bv})"), row));
        }
        if let Some(gap) = pet_gap(c, &ends) {
            gaps.push(gap);
        }
    }
    let mut h =
        Timeline { title: "Conflict-zone occupancy".into(), rows, t_range, gaps, legend: Vec::new() }.svg("occupancy");
    for c in conflicts {
        if let PetOutcome::Censored { pet_lower_bound_s: lb, .. } = c.pet {
            let _ = write!(
                h,
                "<p class=\"muted\">Zone {}: the second vehicle never entered; PET &gt; {lb:.2} s (censored).</p>",
                esc(&c.bv_id)
            );
        }
    }
    h
}

/// The bracket of a zone's PET between the first vehicle's exit and the second's entry, from the
/// two passages `(enter, exit)`.
fn pet_gap(c: &ConflictResult, ends: &[(f64, Option<f64>)]) -> Option<(f64, f64, String)> {
    let ([a, b], Some(pet)) = (ends, c.pet.pet_s()) else { return None };
    let (first, second) = if a.0 <= b.0 { (a, b) } else { (b, a) };
    let exit = first.1?;
    let label = if pet >= 0.0 { format!("PET {pet:.2} s") } else { format!("overlap {:.2} s", -pet) };
    Some((exit.min(second.0), exit.max(second.0), label))
}

fn realism(run: &RunFile) -> String {
    let Some(r) = &run.realism else {
        return "<p class=\"muted\">Realism: not measured in this run (no human reference given).</p>".into();
    };
    let rows: Vec<Vec<String>> = r
        .vehicles
        .iter()
        .map(|v| {
            let mut row = vec![esc(&v.id), esc(v.class.name())];
            match &v.realism {
                None => {
                    row.push("no human reference for this class".into());
                    row.extend(std::iter::repeat_n("–".to_owned(), 4));
                }
                Some(m) => {
                    row.push(num(Some(m.w1_accel_mps2), 3));
                    row.push(num(Some(m.w1_jerk_mps3), 3));
                    row.push(num(Some(m.w1_yaw_rate_radps), 4));
                    row.push(num(Some(m.jerk_rms_mps3), 2));
                    row.push(m.speed_reversals.to_string());
                }
            }
            row
        })
        .collect();
    format!(
        "<h3>Realism against recorded human driving</h3>{}<p class=\"muted\">W<sub>1</sub>: Wasserstein-1 distance between this \
         run's distribution and the recorded human driving of the same manoeuvre class; smaller is more human.</p>",
        table(
            "realism",
            &[
                "vehicle",
                "class",
                "W<sub>1</sub> accel (m/s²)",
                "W<sub>1</sub> jerk (m/s³)",
                "W<sub>1</sub> yaw rate (rad/s)",
                "jerk RMS (m/s³)",
                "speed reversals"
            ],
            &rows
        )
    )
}

/// `file` as a link from a report written to `report`: its name when both are in one folder,
/// else its absolute path.
pub fn link(report: &std::path::Path, file: &std::path::Path) -> String {
    let dir = |p: &std::path::Path| {
        p.parent().map(|d| if d.as_os_str().is_empty() { std::path::PathBuf::from(".") } else { d.to_owned() })
    };
    let same = dir(report)
        .zip(dir(file))
        .is_some_and(|(a, b)| a == b || a.canonicalize().ok().zip(b.canonicalize().ok()).is_some_and(|(x, y)| x == y));
    match (same, file.file_name()) {
        (true, Some(name)) => name.to_string_lossy().into_owned(),
        _ => std::path::absolute(file).unwrap_or_else(|_| file.to_owned()).display().to_string(),
    }
}

/// A whole page of one run (`video2track sim --report`, `v2t-sim-ecu --report`): `files` are the
/// run's other outputs, linked when given.
pub fn page(
    run: &RunFile,
    map: Option<&v2t_map::Map>,
    map_path: &std::path::Path,
    provenance: &str,
    report: &std::path::Path,
    files: &[(&str, Option<&std::path::Path>)],
) -> String {
    let r = &run.result;
    let title = format!("Run {} — VUT {}, BV {}, seed {}", r.scenario, r.vut_model, r.bv_controller, r.seed);
    let ground = match map {
        Some(_) => format!("the map {}", map_path.display()),
        None => "the scenario's own routes (a scenario card: no OpenDRIVE map)".to_owned(),
    };
    let input = RunInput {
        id: "run".into(),
        title: title.clone(),
        run,
        map,
        ground,
        links: files.iter().filter_map(|(label, p)| Some(((*label).to_owned(), link(report, (*p)?)))).collect(),
        facts: Vec::new(),
    };
    let mut p = super::Page::new(&title);
    p.provenance.push(provenance.to_owned());
    p.body = section(&input);
    p.html()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;

    fn run_file() -> RunFile {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let scenario = v2t_sim::files::load_scenario(&root.join("config/scenarios/left_turn_basic.toml")).unwrap();
        let vut = crate::vut::Vut::Builtin(scenario.vut.default_model);
        RunFile::of(&crate::sim::run_reference(&scenario, &vut, 1).unwrap())
    }

    fn section_of(run: &RunFile) -> String {
        section(&RunInput {
            id: "run".into(),
            title: "a run".into(),
            run,
            map: None,
            ground: "its routes".into(),
            links: Vec::new(),
            facts: Vec::new(),
        })
    }

    /// A whole run draws every part; a part the file lacks is said to be missing, and nothing
    /// reads as NaN.
    #[test]
    fn a_run_is_drawn_and_what_its_file_lacks_is_said() {
        let run = run_file();
        let full = section_of(&run);
        for part in ["<svg class=\"map\"", "class=\"zone\"", "class=\"route\"", "class=\"plot pet\"", "PET "] {
            assert!(full.contains(part), "`{part}` missing");
        }
        assert!(full.contains("none in this run (the BVs followed their references)"));
        assert!(full.contains("Actuation gate: none in this world"));
        assert!(full.contains("Realism: not measured in this run"));
        assert!(!full.contains("no layout"));
        let mut old = run;
        old.layout = None;
        old.result.bv_controller = "regulator".into();
        old.result.min_distance_m = f64::INFINITY;
        let h = section_of(&old);
        assert!(h.contains("This run file has no layout") && !h.contains("class=\"zone\""), "no zones without it");
        assert!(h.contains("Regulator: its decisions are not in this run file."));
        assert!(h.contains("– (fewer than two vehicles)") && !h.contains("closest approach ("));
        assert!(!h.contains("NaN") && !full.contains("NaN"));
        assert!(!full.contains("class=\"plot reaction\""), "no regulator, no identification");
    }

    /// A regulated run's plans carry how the VUT was identified to react: the page draws it.
    #[test]
    fn a_regulated_run_draws_what_its_regulator_identified_of_the_vut() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let scenario = v2t_sim::files::load_scenario(&root.join("config/scenarios/left_turn_basic.toml")).unwrap();
        let vut = crate::vut::Vut::Builtin(scenario.vut.default_model);
        let settings: v2t_game::regulator::RegulatorParams =
            v2t_files::load_toml(&root.join("config/regulator/default.toml")).unwrap();
        let run = crate::campaign::regulated_run(&settings, &scenario, &vut, 1, None).unwrap();
        let plans = run.plans();
        assert!(plans[0].iter().all(|p| p.vut_reacts_p.is_some_and(|x| (0.0..=1.0).contains(&x))));
        let file = RunFile { regulator: Some(plans), ..RunFile::of(&run.outcome) };
        let html = section_of(&file);
        assert!(html.contains("class=\"plot reaction\"") && html.contains("probability that it reacts"), "drawn");
        assert!(!html.contains("NaN"));
    }
}
