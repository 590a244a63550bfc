//! SVG drawings of a map in the track frame. One drawing of the lanes and their marks ([`lanes`])
//! lies under both the `map` command's drawing of the topology library ([`render`]: maneuver paths
//! of every fragment and anchors coloured by kind, ids as tooltips) and the map of a run's report
//! (`v2t-lab`), which draws its own layers on top.
//!
//! A [`View`] opens a drawing: its `viewBox` is a [`Window`] of the track frame in metres, and a
//! group mirrors y so that north is up; everything drawn inside that group is in track
//! coordinates. Text goes after the group at `(x, −y)` (or inside it, flipped back) so that it
//! reads upright.

use std::fmt::Write;

use v2t_model::geometry::Point2;
use v2t_model::text::xml_escape;

use crate::Map;
use crate::boundaries::simplify;
use crate::library::{AnchorKind, FragmentKind, TopologyLibrary};
use crate::xodr::MarkType;

/// The style of the lanes and marks: strokes as wide on screen at any scale.
const CSS: &str = ".map .lane{stroke:none}\
.map .mark{fill:none;stroke:#fff;vector-effect:non-scaling-stroke;stroke-width:1.2}\
.map .maneuver{fill:none;vector-effect:non-scaling-stroke;stroke-width:1;opacity:.6}";

/// The ground around the lanes.
const GROUND: &str = "#eef0ea";

/// Tolerance of the simplified lane outlines and marks, m.
const SIMPLIFY_M: f64 = 0.05;

/// A rectangle of the track frame, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// West edge.
    pub x0: f64,
    /// South edge.
    pub y0: f64,
    /// East edge.
    pub x1: f64,
    /// North edge.
    pub y1: f64,
}

impl Window {
    /// The smallest window that holds every finite point; `None` when there is none.
    pub fn around(points: impl IntoIterator<Item = Point2>) -> Option<Self> {
        let inf = f64::INFINITY;
        let (x0, y0, x1, y1) = points
            .into_iter()
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .fold((inf, inf, -inf, -inf), |b, p| (b.0.min(p.x), b.1.min(p.y), b.2.max(p.x), b.3.max(p.y)));
        x0.is_finite().then_some(Self { x0, y0, x1, y1 })
    }

    /// This window grown by `m` on every side.
    pub fn grown(self, m: f64) -> Self {
        Self { x0: self.x0 - m, y0: self.y0 - m, x1: self.x1 + m, y1: self.y1 + m }
    }

    /// Width, m.
    pub fn width(&self) -> f64 {
        self.x1 - self.x0
    }

    /// Height, m.
    pub fn height(&self) -> f64 {
        self.y1 - self.y0
    }

    /// Whether `p` lies inside (edges included).
    pub fn contains(&self, p: Point2) -> bool {
        p.x >= self.x0 && p.x <= self.x1 && p.y >= self.y0 && p.y <= self.y1
    }
}

/// A drawing of a window of the track frame at a scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// What the drawing shows.
    pub window: Window,
    /// Its scale, px per m.
    pub px_per_m: f64,
}

impl View {
    /// Ends the mirrored group [`View::open`] opened: text drawn after it goes at `(x, −y)`.
    pub const UPRIGHT: &'static str = "</g>";

    /// `px` screen pixels in the drawing's units (m): widths, radii, font sizes.
    pub fn m(&self, px: f64) -> f64 {
        px / self.px_per_m
    }

    /// Opens the drawing: `<svg class="map…">` with `title`, the style of the lanes and marks, the
    /// ground, and the group that mirrors y (closed by [`View::UPRIGHT`]). `class` is added to
    /// `map`; `standalone`: a file of its own (with the SVG namespace), else a part of a page.
    pub fn open(&self, class: &str, title: &str, standalone: bool) -> String {
        let w = &self.window;
        let (width, height) = (w.width(), w.height());
        let class = if class.is_empty() { "map".to_owned() } else { format!("map {class}") };
        let ns = if standalone { " xmlns=\"http://www.w3.org/2000/svg\"" } else { "" };
        format!(
            "<svg class=\"{class}\"{ns} width=\"{:.0}\" height=\"{:.0}\" viewBox=\"{:.2} {:.2} {width:.2} {height:.2}\" \
             role=\"img\"><title>{}</title><style>{CSS}</style>\
             <rect class=\"ground\" x=\"{:.2}\" y=\"{:.2}\" width=\"{width:.2}\" height=\"{height:.2}\" fill=\"{GROUND}\"/>\
             <g transform=\"scale(1 -1)\">",
            width * self.px_per_m,
            height * self.px_per_m,
            w.x0,
            -w.y1,
            xml_escape(title),
            w.x0,
            -w.y1,
        )
    }

    /// A scale bar of a round length at the bottom left, labelled in metres (after
    /// [`View::UPRIGHT`]).
    pub fn scale_bar(&self) -> String {
        let w = &self.window;
        let bar = round_length(w.width() / 5.0);
        format!(
            "<g class=\"scalebar\"><path d=\"M{:.2} {:.2} h{bar:.2}\" stroke=\"#222\" stroke-width=\"{:.3}\"/>\
             <text x=\"{:.2}\" y=\"{:.2}\" font-size=\"{:.3}\">{bar:.0} m</text></g>",
            w.x0 + 2.0,
            -w.y0 - 2.0,
            self.m(2.0),
            w.x0 + 2.0,
            -w.y0 - 3.0 - self.m(2.0),
            self.m(11.0)
        )
    }
}

/// The largest of 1, 2, 5 × 10ⁿ m not longer than `target` m.
fn round_length(target: f64) -> f64 {
    let mag = 10f64.powf(target.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).rfind(|v| *v <= target).unwrap_or(mag)
}

/// The `d` of a path through `points` (track coordinates, 1 cm), skipping non-finite points.
pub fn path_d(points: impl IntoIterator<Item = (f64, f64)>) -> String {
    let mut d = String::new();
    for (i, (x, y)) in points.into_iter().filter(|(x, y)| x.is_finite() && y.is_finite()).enumerate() {
        let _ = write!(d, "{}{x:.2} {y:.2}", if i == 0 { "M" } else { " L" });
    }
    d
}

fn points_d(points: &[Point2]) -> String {
    path_d(points.iter().map(|p| (p.x, p.y)))
}

/// The map's lane surfaces (`<g class="lanes">`, drivable and not) and the marks on their
/// boundaries (`<g class="marks">`: solid, broken, mixed), in track coordinates; with a `window`
/// only the stretches inside it.
pub fn lanes(map: &Map, window: Option<&Window>) -> String {
    let mut lanes = String::from("<g class=\"lanes\">");
    let mut marks = String::from("<g class=\"marks\">");
    for lane in &map.graph.lanes {
        // Runs of consecutive samples inside the window.
        let mut runs: Vec<Vec<&crate::graph::LaneSample>> = Vec::new();
        let mut cur = Vec::new();
        for q in &lane.samples {
            if window.is_none_or(|w| w.contains(q.p)) {
                cur.push(q);
            } else if !cur.is_empty() {
                runs.push(std::mem::take(&mut cur));
            }
        }
        if !cur.is_empty() {
            runs.push(cur);
        }
        for run in runs.iter().filter(|r| r.len() >= 2) {
            let outline: Vec<Point2> = run.iter().map(|q| q.left).chain(run.iter().rev().map(|q| q.right)).collect();
            let _ = write!(
                lanes,
                "<path class=\"lane\" fill=\"{}\" d=\"{}Z\"><title>{} ({})</title></path>",
                if lane.drivable { "#c3c7cc" } else { "#dde2d6" },
                points_d(&simplify(&outline, SIMPLIFY_M)),
                lane.key,
                xml_escape(&lane.kind)
            );
            for left in [true, false] {
                boundary_marks(&mut marks, run, left);
            }
        }
    }
    lanes.push_str("</g>");
    marks.push_str("</g>");
    lanes + &marks
}

/// The marks along one boundary of a run of lane samples, split where the mark changes.
fn boundary_marks(out: &mut String, run: &[&crate::graph::LaneSample], left: bool) {
    let flush = |out: &mut String, seg: &[Point2], kind: Option<MarkType>| {
        let dash = match kind {
            Some(MarkType::Broken) => " stroke-dasharray=\"6 6\"",
            Some(MarkType::Mixed) => " stroke-dasharray=\"12 3\"",
            _ => "",
        };
        if seg.len() >= 2 && !matches!(kind, Some(MarkType::None) | None) {
            let _ = write!(out, "<path class=\"mark\"{dash} d=\"{}\"/>", points_d(&simplify(seg, SIMPLIFY_M)));
        }
    };
    let mut seg: Vec<Point2> = Vec::new();
    let mut kind: Option<MarkType> = None;
    for q in run {
        let (p, m) = if left { (q.left, q.left_mark) } else { (q.right, q.right_mark) };
        if kind != Some(m) {
            if let Some(last) = seg.last().copied() {
                flush(out, &seg, kind);
                seg = vec![last];
            }
            kind = Some(m);
        }
        seg.push(p);
    }
    flush(out, &seg, kind);
}

fn colour(kind: AnchorKind) -> &'static str {
    match kind {
        AnchorKind::Entry => "#2a9d8f",
        AnchorKind::Exit => "#264653",
        AnchorKind::Conflict => "#e63946",
        AnchorKind::Merge => "#f4a261",
        AnchorKind::CutIn => "#9b5de5",
    }
}

fn fragment_colour(kind: FragmentKind) -> &'static str {
    match kind {
        FragmentKind::Intersection => "#e76f51",
        FragmentKind::MultiLaneSegment => "#457b9d",
        FragmentKind::Merge => "#e9c46a",
    }
}

/// The map and its topology library as an SVG file: the [`lanes`] and marks, then every fragment's
/// maneuver paths, anchors and name.
pub fn render(map: &Map, lib: &TopologyLibrary) -> String {
    let edges = map.graph.lanes.iter().flat_map(|l| l.samples.iter().flat_map(|q| [q.left, q.right]));
    let window = Window::around(edges).map_or(Window { x0: 0.0, y0: 0.0, x1: 1.0, y1: 1.0 }, |w| w.grown(10.0));
    let view = View { window, px_per_m: (1600.0 / window.width().max(window.height())).min(8.0) };
    let mut s = view.open("", &map.name, true);
    s.push_str(&lanes(map, None));
    for f in &lib.fragments {
        let c = fragment_colour(f.kind);
        let _ = write!(
            s,
            "<g id=\"{}\" class=\"fragment\"><title>{}</title>",
            xml_escape(&f.id),
            xml_escape(&f.description)
        );
        for m in &f.maneuvers {
            let _ = write!(
                s,
                "<path class=\"maneuver\" d=\"{}\" stroke=\"{c}\"><title>{}</title></path>",
                points_d(&m.path),
                xml_escape(&m.id)
            );
        }
        for a in &f.anchors {
            let _ = write!(
                s,
                "<circle cx=\"{:.2}\" cy=\"{:.2}\" r=\"{:.3}\" fill=\"{}\"><title>{}</title></circle>",
                a.position.x,
                a.position.y,
                view.m(3.0),
                colour(a.kind),
                xml_escape(&a.id)
            );
        }
        // Flipped back inside the mirrored group, so that it reads upright.
        let _ = write!(
            s,
            "<text transform=\"matrix(1 0 0 -1 {:.2} {:.2})\" font-family=\"sans-serif\" font-size=\"{:.3}\" fill=\"{c}\">{}</text></g>",
            f.centre.x,
            f.centre.y,
            view.m(12.0),
            xml_escape(f.name.as_deref().unwrap_or(&f.id))
        );
    }
    s.push_str(View::UPRIGHT);
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_holds_its_finite_points_and_a_view_mirrors_y() {
        let pts = [Point2 { x: 1.0, y: -2.0 }, Point2 { x: f64::NAN, y: 0.0 }, Point2 { x: 5.0, y: 4.0 }];
        let w = Window::around(pts).map(|w| w.grown(1.0));
        assert_eq!(w, Some(Window { x0: 0.0, y0: -3.0, x1: 6.0, y1: 5.0 }));
        assert_eq!(Window::around([Point2 { x: f64::INFINITY, y: 0.0 }]), None);
        let view = View { window: Window { x0: 0.0, y0: -3.0, x1: 6.0, y1: 5.0 }, px_per_m: 10.0 };
        let s = view.open("", "a <map>", false);
        assert!(s.starts_with("<svg class=\"map\" width=\"60\" height=\"80\" viewBox=\"0.00 -5.00 6.00 8.00\""), "{s}");
        assert!(s.ends_with("<g transform=\"scale(1 -1)\">") && s.contains("<title>a &lt;map&gt;</title>"));
        assert!(!s.contains("xmlns") && view.open("x", "", true).contains("class=\"map x\" xmlns="));
        assert!(view.scale_bar().contains(">1 m</text>"), "{}", view.scale_bar());
        assert_eq!(path_d([(0.0, 1.0), (f64::NAN, 0.0), (2.0, 3.0)]), "M0.00 1.00 L2.00 3.00");
    }

    #[test]
    fn round_lengths() {
        assert_eq!(round_length(27.0), 20.0);
        assert_eq!(round_length(60.0), 50.0);
        assert_eq!(round_length(9.9), 5.0);
        assert_eq!(round_length(100.0), 100.0);
    }
}
