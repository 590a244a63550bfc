//! CommonRoad XML scenarios: dynamic obstacles as tracks, lanelets as a [`LaneletNetwork`].
//!
//! The formats found in published scenarios are read: **2020a** (`dynamicObstacle`), the older
//! **2018b** (`obstacle` with `<role>dynamic</role>`; static obstacles are skipped), and **2018a**
//! (and its predecessor **2017a**), written like 2018b but without an `initialState` (the first
//! `state` of the trajectory is the start) and with `time` in seconds instead of steps. Every
//! dynamic obstacle becomes a [`Track`]: its `initialState` and the `state`s of its `trajectory`,
//! each at `time × timeStepSize` (the scenario's attribute; 2018a and 2017a: at `time`, on the grid
//! of `timeStepSize`). A state gives
//! `position/point/{x,y}` (or the centre of a `rectangle`/`circle` position), `orientation`,
//! `time` and `velocity`, each either `exact` or an interval (`intervalStart`/`intervalEnd`; the
//! midpoint is used, for time the start). CommonRoad's velocity is along the orientation, so
//! `vx = v cos ψ`, `vy = v sin ψ`. `type` and `shape/rectangle/{length,width}` give the kind and
//! footprint. Every `lanelet` (both formats: `leftBound`/`rightBound` point lists with an optional
//! `lineMarking`, `predecessor`/`successor`/`adjacentLeft`/`adjacentRight` references) goes into
//! the [`LaneletNetwork`] ([`parse_scenario`]). Traffic signs, lights and intersections are
//! ignored. Errors name the line.

use v2t_model::metrics::Dimensions;

use v2t_model::geometry::Point2;

use crate::lanes::{Adjacent, Lanelet, LaneletNetwork};
use crate::tracks::{AgentKind, Episode, Track, TrackSample};

/// What can go wrong reading a CommonRoad file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CommonRoadError {
    /// Not well-formed XML.
    #[error("XML: {0}")]
    Xml(String),
    /// The root element is not `commonRoad`.
    #[error("root element is `{0}`, expected `commonRoad`")]
    NotCommonRoad(String),
    /// `timeStepSize` missing or not a positive finite number.
    #[error("line {line}: timeStepSize `{value}` is not a number in (0, {MAX_TIME_STEP_SIZE_S}] s")]
    TimeStepSize {
        /// Line of the root element.
        line: u32,
        /// The attribute's text.
        value: String,
    },
    /// A required element is absent.
    #[error("line {line}: obstacle `{obstacle}`: no `{what}`")]
    Missing {
        /// Line of the state (or obstacle).
        line: u32,
        /// Obstacle id.
        obstacle: String,
        /// What is missing.
        what: &'static str,
    },
    /// A value that is not a finite number.
    #[error("line {line}: obstacle `{obstacle}`: `{element}` is `{value}`, not a finite number")]
    Number {
        /// Line of the element.
        line: u32,
        /// Obstacle id.
        obstacle: String,
        /// Element name.
        element: String,
        /// Its text.
        value: String,
    },
    /// A number outside what a recording can hold (a coordinate beyond [`MAX_COORDINATE_M`], a
    /// time step beyond [`MAX_TIME_STEP`], a step size beyond (0, [`MAX_TIME_STEP_SIZE_S`]]).
    #[error("line {line}: `{element}` is {value:e}, outside ±{bound:e} (obstacle or lanelet `{id}`)")]
    Range {
        /// Line of the element.
        line: u32,
        /// Obstacle or lanelet id.
        id: String,
        /// Element name.
        element: String,
        /// The value.
        value: f64,
        /// The bound.
        bound: f64,
    },
    /// Two states of one obstacle at the same time step.
    #[error("line {line}: obstacle `{obstacle}`: time step {step} given twice")]
    DuplicateTime {
        /// Line of the second state.
        line: u32,
        /// Obstacle id.
        obstacle: String,
        /// The time step.
        step: i64,
    },
    /// A lanelet whose bounds are unusable (fewer than two points, or left and right counts that
    /// differ).
    #[error("line {line}: lanelet `{lanelet}`: {reason}")]
    Lanelet {
        /// Line of the lanelet.
        line: u32,
        /// Lanelet id.
        lanelet: String,
        /// What is wrong.
        reason: String,
    },
    /// A version this reader does not know.
    #[error("line {line}: commonRoadVersion `{version}` is not one of 2017a, 2018a, 2018b, 2020a")]
    Version {
        /// Line of the root element.
        line: u32,
        /// The attribute's text.
        version: String,
    },
    /// The file could not be read.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        message: String,
    },
}

type Node<'a, 'i> = roxmltree::Node<'a, 'i>;

/// Coordinates beyond this are refused, m: a scenario's frame is local (published ones stay within
/// a few kilometres), and mining and inverse kinematics work in memory proportional to distances.
pub const MAX_COORDINATE_M: f64 = 1e6;
/// Time steps beyond this are refused (10⁷ steps of 0.1 s are 11 days).
pub const MAX_TIME_STEP: f64 = 1e7;
/// Step sizes beyond this are refused, s.
pub const MAX_TIME_STEP_SIZE_S: f64 = 10.0;

/// `value` of `node` within ±`bound`, or a [`CommonRoadError::Range`].
fn within(
    doc: &roxmltree::Document<'_>,
    node: Node<'_, '_>,
    id: &str,
    value: f64,
    bound: f64,
) -> Result<f64, CommonRoadError> {
    if value.abs() <= bound {
        Ok(value)
    } else {
        Err(CommonRoadError::Range {
            line: line(doc, node),
            id: id.to_owned(),
            element: node.tag_name().name().to_owned(),
            value,
            bound,
        })
    }
}

/// The `x` and `y` children of `p`, each within ±[`MAX_COORDINATE_M`].
fn xy(doc: &roxmltree::Document<'_>, p: Node<'_, '_>, id: &str) -> Result<Option<(f64, f64)>, CommonRoadError> {
    let coordinate = |name: &str| -> Result<Option<f64>, CommonRoadError> {
        let Some(n) = child(p, name) else { return Ok(None) };
        within(doc, n, id, number(doc, n, id)?, MAX_COORDINATE_M).map(Some)
    };
    Ok(coordinate("x")?.zip(coordinate("y")?))
}

fn line(doc: &roxmltree::Document<'_>, node: Node<'_, '_>) -> u32 {
    doc.text_pos_at(node.range().start).row
}

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.has_tag_name(name))
}

/// Reads a finite number from the text of `node`.
fn number(doc: &roxmltree::Document<'_>, node: Node<'_, '_>, obstacle: &str) -> Result<f64, CommonRoadError> {
    let text = node.text().unwrap_or("").trim();
    text.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| CommonRoadError::Number {
        line: line(doc, node),
        obstacle: obstacle.to_owned(),
        element: node.tag_name().name().to_owned(),
        value: text.to_owned(),
    })
}

/// An `exact` value, or the midpoint of `intervalStart`/`intervalEnd` (the start alone when
/// `start_only`). `None` when the element is absent.
fn value(
    doc: &roxmltree::Document<'_>,
    parent: Node<'_, '_>,
    name: &str,
    obstacle: &str,
    start_only: bool,
) -> Result<Option<f64>, CommonRoadError> {
    let Some(el) = child(parent, name) else { return Ok(None) };
    if let Some(exact) = child(el, "exact") {
        return number(doc, exact, obstacle).map(Some);
    }
    let start = child(el, "intervalStart").map(|n| number(doc, n, obstacle)).transpose()?;
    let end = child(el, "intervalEnd").map(|n| number(doc, n, obstacle)).transpose()?;
    Ok(match (start, end) {
        (Some(a), _) if start_only => Some(a),
        (Some(a), Some(b)) => Some(0.5 * (a + b)),
        (a, b) => a.or(b),
    })
}

/// `(x, y)` of a `position`: its point, or the centre of its rectangle or circle.
fn position(
    doc: &roxmltree::Document<'_>,
    state: Node<'_, '_>,
    obstacle: &str,
) -> Result<Option<(f64, f64)>, CommonRoadError> {
    let Some(pos) = child(state, "position") else { return Ok(None) };
    let point = child(pos, "point").or_else(|| {
        ["rectangle", "circle"].into_iter().find_map(|shape| child(pos, shape).and_then(|s| child(s, "center")))
    });
    let Some(p) = point else { return Ok(None) };
    xy(doc, p, obstacle)
}

/// One state: its step on the scenario's grid of `dt_s` and its sample. `time_in_seconds`: the
/// file writes `time` in seconds (2018a, 2017a), not in steps.
fn state_sample(
    doc: &roxmltree::Document<'_>,
    state: Node<'_, '_>,
    obstacle: &str,
    dt_s: f64,
    time_in_seconds: bool,
) -> Result<(i64, TrackSample), CommonRoadError> {
    let missing = |what| CommonRoadError::Missing { line: line(doc, state), obstacle: obstacle.to_owned(), what };
    let (x, y) = position(doc, state, obstacle)?.ok_or_else(|| missing("position/point"))?;
    let raw_step = value(doc, state, "time", obstacle, true)?.ok_or_else(|| missing("time"))?;
    let time_node = child(state, "time").unwrap_or(state);
    let raw_step = if time_in_seconds { raw_step / dt_s } else { raw_step };
    let step = within(doc, time_node, obstacle, raw_step, MAX_TIME_STEP)?.round() as i64;
    let psi = value(doc, state, "orientation", obstacle, false)?;
    let v = value(doc, state, "velocity", obstacle, false)?;
    let (vx, vy) = match (v, psi) {
        (Some(v), Some(psi)) => (Some(v * psi.cos()), Some(v * psi.sin())),
        _ => (None, None),
    };
    Ok((step, TrackSample { t_s: step as f64 * dt_s, x_m: x, y_m: y, vx_mps: vx, vy_mps: vy, psi_rad: psi }))
}

/// A parsed scenario: its tracks and its lanelet network.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// The dynamic obstacles as tracks, named after the `benchmarkID` (or the given name).
    pub episode: Episode,
    /// The lanelets.
    pub lanes: LaneletNetwork,
    /// `commonRoadVersion` as written (empty when absent).
    pub version: String,
    /// The `source` attribute (e.g. `NGSIM`), empty when absent.
    pub source: String,
}

/// Whether `node` is a dynamic obstacle of either format.
fn is_dynamic_obstacle(node: Node<'_, '_>) -> bool {
    node.has_tag_name("dynamicObstacle")
        || (node.has_tag_name("obstacle")
            && child(node, "role").and_then(|r| r.text()).is_some_and(|r| r.trim() == "dynamic"))
}

fn bound_points(doc: &roxmltree::Document<'_>, bound: Node<'_, '_>, id: &str) -> Result<Vec<Point2>, CommonRoadError> {
    let mut out = Vec::new();
    for p in bound.children().filter(|c| c.has_tag_name("point")) {
        match xy(doc, p, id)? {
            Some((x, y)) => out.push(Point2::new(x, y)),
            None => {
                return Err(CommonRoadError::Lanelet {
                    line: line(doc, p),
                    lanelet: id.to_owned(),
                    reason: "a bound point without x or y".into(),
                });
            }
        }
    }
    Ok(out)
}

fn lanelet(doc: &roxmltree::Document<'_>, node: Node<'_, '_>) -> Result<Lanelet, CommonRoadError> {
    let id = node.attribute("id").unwrap_or("").to_owned();
    let err = |reason: String| CommonRoadError::Lanelet { line: line(doc, node), lanelet: id.clone(), reason };
    let bound = |name: &str| -> Result<(Vec<Point2>, Option<String>), CommonRoadError> {
        let b = child(node, name).ok_or_else(|| err(format!("no `{name}`")))?;
        let marking = child(b, "lineMarking").and_then(|m| m.text()).map(|t| t.trim().to_owned());
        Ok((bound_points(doc, b, &id)?, marking))
    };
    let (left, left_marking) = bound("leftBound")?;
    let (right, right_marking) = bound("rightBound")?;
    if left.len() < 2 || left.len() != right.len() {
        return Err(err(format!(
            "left bound has {} points and right bound {}: both need the same count, at least 2",
            left.len(),
            right.len()
        )));
    }
    let refs = |name: &str| -> Vec<String> {
        node.children().filter(|c| c.has_tag_name(name)).filter_map(|c| c.attribute("ref")).map(str::to_owned).collect()
    };
    let adjacent = |name: &str| {
        child(node, name).and_then(|a| {
            Some(Adjacent {
                id: a.attribute("ref")?.to_owned(),
                same_direction: a.attribute("drivingDir") != Some("opposite"),
            })
        })
    };
    Ok(Lanelet {
        id: id.clone(),
        left,
        right,
        left_marking,
        right_marking,
        predecessors: refs("predecessor"),
        successors: refs("successor"),
        adjacent_left: adjacent("adjacentLeft"),
        adjacent_right: adjacent("adjacentRight"),
    })
}

/// Parses CommonRoad XML (2020a, 2018b, 2018a or 2017a) into its tracks and lanelet network.
pub fn parse_scenario(xml: &str, name: &str) -> Result<Scenario, CommonRoadError> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| CommonRoadError::Xml(e.to_string()))?;
    let root = doc.root_element();
    if !root.has_tag_name("commonRoad") {
        return Err(CommonRoadError::NotCommonRoad(root.tag_name().name().to_owned()));
    }
    let version = root.attribute("commonRoadVersion").unwrap_or("").trim().to_owned();
    if !matches!(version.as_str(), "" | "2017a" | "2018a" | "2018b" | "2020a") {
        return Err(CommonRoadError::Version { line: line(&doc, root), version });
    }
    let raw = root.attribute("timeStepSize").unwrap_or("");
    let dt_s = raw
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0 && *v <= MAX_TIME_STEP_SIZE_S)
        .ok_or_else(|| CommonRoadError::TimeStepSize { line: line(&doc, root), value: raw.to_owned() })?;
    let time_in_seconds = matches!(version.as_str(), "2017a" | "2018a");
    let mut tracks = Vec::new();
    for obstacle in root.children().filter(|c| is_dynamic_obstacle(*c)) {
        let id = obstacle.attribute("id").unwrap_or("").to_owned();
        let kind = child(obstacle, "type").and_then(|t| t.text()).map_or(AgentKind::Unknown, AgentKind::from_label);
        let dims = child(obstacle, "shape").and_then(|s| child(s, "rectangle")).and_then(|r| {
            let l = child(r, "length").and_then(|n| number(&doc, n, &id).ok())?;
            let w = child(r, "width").and_then(|n| number(&doc, n, &id).ok())?;
            Some(Dimensions { length_m: l, width_m: w })
        });
        let mut states: Vec<Node<'_, '_>> = child(obstacle, "initialState").into_iter().collect();
        if let Some(traj) = child(obstacle, "trajectory") {
            states.extend(traj.children().filter(|c| c.has_tag_name("state")));
        }
        if states.is_empty() {
            return Err(CommonRoadError::Missing { line: line(&doc, obstacle), obstacle: id, what: "initialState" });
        }
        let mut samples: Vec<(i64, u32, TrackSample)> = Vec::with_capacity(states.len());
        for s in states {
            let (step, sample) = state_sample(&doc, s, &id, dt_s, time_in_seconds)?;
            samples.push((step, line(&doc, s), sample));
        }
        samples.sort_by_key(|s| s.0);
        for w in samples.windows(2) {
            if let [a, b] = w
                && a.0 == b.0
            {
                return Err(CommonRoadError::DuplicateTime { line: a.1.max(b.1), obstacle: id, step: b.0 });
            }
        }
        tracks.push(Track { id, dt_s, kind, dims, samples: samples.into_iter().map(|s| s.2).collect() });
    }
    let lanelets = root
        .children()
        .filter(|c| c.has_tag_name("lanelet"))
        .map(|l| lanelet(&doc, l))
        .collect::<Result<Vec<_>, _>>()?;
    let name = root.attribute("benchmarkID").filter(|s| !s.trim().is_empty()).unwrap_or(name);
    Ok(Scenario {
        episode: Episode::from_tracks(name, tracks),
        lanes: LaneletNetwork::new(lanelets),
        version,
        source: root.attribute("source").unwrap_or("").to_owned(),
    })
}

/// Parses CommonRoad XML into an episode named after its `benchmarkID` (or `name`).
pub fn parse(xml: &str, name: &str) -> Result<Episode, CommonRoadError> {
    parse_scenario(xml, name).map(|s| s.episode)
}

/// Reads and parses a CommonRoad file (tracks and lanelets); `name` defaults to the file stem.
pub fn parse_scenario_file(path: &std::path::Path) -> Result<Scenario, CommonRoadError> {
    let text = v2t_files::bounds::read_text_within(path, v2t_files::bounds::DRIVING_DATA)
        .map_err(|e| CommonRoadError::Io { path: path.display().to_string(), message: e.to_string() })?;
    let stem = path.file_stem().map_or_else(|| "commonroad".to_owned(), |s| s.to_string_lossy().into_owned());
    parse_scenario(&text, &stem)
}

/// Reads and parses a CommonRoad file; `name` defaults to the file stem.
pub fn parse_file(path: &std::path::Path) -> Result<Episode, CommonRoadError> {
    parse_scenario_file(path).map(|s| s.episode)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// One state element as CommonRoad writes it.
    fn state_xml(tag: &str, step: i64, x: f64, y: f64, psi: f64, v: f64) -> String {
        format!(
            "<{tag}><position><point><x>{x}</x><y>{y}</y></point></position>\
             <orientation><exact>{psi}</exact></orientation><time><exact>{step}</exact></time>\
             <velocity><exact>{v}</exact></velocity></{tag}>"
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn written_obstacles_read_back(
            dt in prop::sample::select(vec![0.04, 0.1, 0.2]),
            obstacles in prop::collection::vec(
                (0i64..20, prop::collection::vec((-1e3f64..1e3, -1e3f64..1e3, -3.1f64..3.1, 0.0f64..40.0), 1..12)),
                1..4),
        ) {
            let mut xml = format!("<commonRoad commonRoadVersion=\"2020a\" benchmarkID=\"P\" timeStepSize=\"{dt}\">");
            for (i, (start, states)) in obstacles.iter().enumerate() {
                xml.push_str(&format!("<dynamicObstacle id=\"{}\"><type>car</type>", 100 + i));
                xml.push_str("<shape><rectangle><length>4.5</length><width>1.8</width></rectangle></shape>");
                for (k, (x, y, psi, v)) in states.iter().enumerate() {
                    if k == 0 {
                        xml.push_str(&state_xml("initialState", *start, *x, *y, *psi, *v));
                        xml.push_str("<trajectory>");
                    } else {
                        xml.push_str(&state_xml("state", start + k as i64, *x, *y, *psi, *v));
                    }
                }
                xml.push_str("</trajectory></dynamicObstacle>");
            }
            xml.push_str("</commonRoad>");
            let e = parse(&xml, "p").unwrap();
            prop_assert_eq!(e.tracks.len(), obstacles.len());
            for (t, (start, states)) in e.tracks.iter().zip(&obstacles) {
                prop_assert_eq!(t.samples.len(), states.len());
                prop_assert!(t.gaps().is_empty());
                for (k, (s, (x, y, psi, v))) in t.samples.iter().zip(states).enumerate() {
                    prop_assert!((s.t_s - (start + k as i64) as f64 * dt).abs() < 1e-9);
                    prop_assert_eq!((s.x_m, s.y_m, s.psi_rad), (*x, *y, Some(*psi)));
                    let speed = s.vx_mps.unwrap().hypot(s.vy_mps.unwrap());
                    prop_assert!((speed - v).abs() < 1e-9);
                }
            }
        }
    }

    fn data(name: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
    }

    #[test]
    fn hand_made_scenario_reads() {
        let e = parse_file(&data("two_vehicles.cr.xml")).unwrap();
        assert_eq!(e.id, "ZAM_V2T-1_1_T-1");
        assert_eq!(e.tracks.len(), 2);
        let a = &e.tracks[0];
        assert_eq!(a.id, "30");
        assert_eq!(a.kind, AgentKind::Car);
        assert_eq!(a.dims, Some(Dimensions { length_m: 4.5, width_m: 1.8 }));
        assert_eq!(a.samples.len(), 4);
        assert!((a.dt_s - 0.1).abs() < 1e-12);
        assert!((a.samples[3].t_s - 0.3).abs() < 1e-12);
        assert!((a.samples[1].x_m - 11.0).abs() < 1e-12);
        assert!((a.samples[0].vx_mps.unwrap() - 10.0).abs() < 1e-12);
        let b = &e.tracks[1];
        assert_eq!(b.kind, AgentKind::Truck);
        // Interval orientation: midpoint; velocity along it.
        assert!((b.samples[1].psi_rad.unwrap() - 1.6).abs() < 1e-12);
        assert!((b.samples[1].vy_mps.unwrap() - 5.0 * 1.6f64.sin()).abs() < 1e-12);
        // Rectangle position: its centre; missing third step is a gap.
        assert!((b.samples[2].y_m - -4.0).abs() < 1e-12);
        assert_eq!(b.gaps(), vec![1]);
    }

    #[test]
    fn errors_name_the_line() {
        let head = r#"<commonRoad commonRoadVersion="2020a" benchmarkID="X" timeStepSize="0.1">"#;
        let state = |x: &str, t: u32| {
            format!(
                "<state><position><point><x>{x}</x><y>0</y></point></position><time><exact>{t}</exact></time></state>"
            )
        };
        let obstacle = |body: String| {
            format!(
                "{head}\n<dynamicObstacle id=\"1\"><type>car</type>\n<initialState><position><point><x>0</x><y>0</y></point></position><time><exact>0</exact></time></initialState>\n<trajectory>{body}</trajectory></dynamicObstacle></commonRoad>"
            )
        };
        let e = parse(&obstacle(state("nan", 1)), "x").unwrap_err();
        assert!(matches!(e, CommonRoadError::Number { line: 4, ref element, .. } if element == "x"), "{e}");
        let e = parse(&obstacle(state("1", 0)), "x").unwrap_err();
        assert!(matches!(e, CommonRoadError::DuplicateTime { line: 4, step: 0, .. }), "{e}");
        let e = parse(&obstacle("<state><time><exact>1</exact></time></state>".into()), "x").unwrap_err();
        assert!(matches!(e, CommonRoadError::Missing { line: 4, what: "position/point", .. }), "{e}");
        let e = parse(&obstacle(state("1e9", 1)), "x").unwrap_err();
        assert!(
            matches!(e, CommonRoadError::Range { line: 4, ref element, bound, .. } if element == "x" && bound == MAX_COORDINATE_M),
            "{e}"
        );
        let far_in_time = obstacle(state("1", 1).replace("<exact>1</exact></time>", "<exact>1e300</exact></time>"));
        let e = parse(&far_in_time, "x").unwrap_err();
        assert!(matches!(e, CommonRoadError::Range { line: 4, ref element, .. } if element == "time"), "{e}");
        assert!(e.to_string().contains("line 4: `time` is 1e300, outside ±1e7"), "{e}");
        let huge_dt = r#"<commonRoad timeStepSize="1e9"></commonRoad>"#;
        assert!(matches!(parse(huge_dt, "x"), Err(CommonRoadError::TimeStepSize { .. })));
        let bad_dt = r#"<commonRoad timeStepSize="-1"></commonRoad>"#;
        assert!(matches!(parse(bad_dt, "x"), Err(CommonRoadError::TimeStepSize { line: 1, .. })));
        assert!(matches!(parse("<OpenDRIVE/>", "x"), Err(CommonRoadError::NotCommonRoad(_))));
        assert!(matches!(parse("<commonRoad", "x"), Err(CommonRoadError::Xml(_))));
        assert_eq!(parse(&obstacle(state("1", 1)), "x").unwrap().tracks[0].samples.len(), 2);
    }

    #[test]
    fn a_2018a_obstacle_starts_with_its_first_state_and_counts_time_in_seconds() {
        // As CommonRoad 2018a writes an obstacle: no initialState, `time` in seconds.
        let state = |t: &str, x: f64| {
            format!(
                "<state><position><point><x>{x}</x><y>0</y></point></position>\
                 <orientation><exact>0</exact></orientation><time><exact>{t}</exact></time>\
                 <velocity><exact>10</exact></velocity><acceleration><exact>0</exact></acceleration></state>"
            )
        };
        let xml = format!(
            "<commonRoad commonRoadVersion=\"2018a\" benchmarkID=\"A\" timeStepSize=\"0.1\">\
             <obstacle id=\"7\"><role>dynamic</role><type>car</type>\
             <shape><rectangle><length>4.7</length><width>1.9</width></rectangle></shape>\
             <trajectory>{}{}{}</trajectory></obstacle></commonRoad>",
            state("0", 0.0),
            state("0.1", 1.0),
            state("0.2", 2.0)
        );
        let s = parse_scenario(&xml, "a").unwrap();
        let t = &s.episode.tracks[0];
        assert_eq!(t.samples.iter().map(|q| q.t_s).collect::<Vec<_>>(), vec![0.0, 0.1, 0.2]);
        assert_eq!(t.samples[2].x_m, 2.0);
        // The same states read as 2018b steps would collapse onto step 0.
        let as_2018b = xml.replace("2018a", "2018b");
        assert!(matches!(parse_scenario(&as_2018b, "a"), Err(CommonRoadError::DuplicateTime { .. })));
        // 2017a is written the same way.
        assert_eq!(parse_scenario(&xml.replace("2018a", "2017a"), "a").unwrap().episode, s.episode);
    }
}
