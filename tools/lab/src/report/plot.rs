//! The project's plots as SVG: line plots with labelled axes and units, bands of states over time,
//! occupancy timelines, strip plots with quartile boxes, scatter plots, and figures of several
//! plots under one title, inline in a report or as a file of their own ([`Figure`]). Pure string
//! building, no script: a plot reads the same printed.

use std::fmt::Write as _;

use super::esc;

/// Colours of series, in order (colour-blind safe, Okabe–Ito).
pub const PALETTE: [&str; 8] = ["#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#000000", "#f0e442"];

/// The colour of series `i`.
pub fn colour(i: usize) -> &'static str {
    PALETTE.get(i % PALETTE.len()).copied().unwrap_or("#000")
}

/// Up to about `n` round tick values covering `[lo, hi]`.
pub fn ticks(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo || n == 0 {
        return vec![lo];
    }
    let raw = (hi - lo) / n as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() * step;
    (0..=n * 2 + 2).map(|k| first + k as f64 * step).take_while(|v| *v <= hi + step * 1e-9).collect()
}

/// A tick label: as few decimals as the step needs.
fn tick_label(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 { 0 } else { (-step.log10().floor()) as usize };
    let v = if v.abs() < step * 1e-9 { 0.0 } else { v };
    format!("{v:.decimals$}")
}

/// The plots' style: a report's page holds it once, a [`Figure`] written as a file holds its own.
pub const CSS: &str = "\
.plot text{font-size:11px;fill:#333}.plot .rowlabel{font-size:11px}.plot .ptitle{font-size:12px;font-weight:600}.plot .axis{font-size:11px;fill:#222}\
.plot .grid line{stroke:#ececec}.plot .frame{fill:none;stroke:#999}.plot .series{fill:none;stroke-width:1.8}\
.plot .level{stroke:#c00;stroke-dasharray:6 4}.plot .levellabel{fill:#c00}.plot .cursor{stroke:#444;stroke-width:1}\
.plot .rowbg{fill:#f6f6f6}.plot .gap path{fill:none;stroke:#c00}.plot .gap text{fill:#c00}\
.plot .box{fill:#dfe7f2;stroke:#5577aa}.plot .median{stroke:#223;stroke-width:2}.plot .reference{stroke:#c00;stroke-width:2}\
.plot .unreachable{fill:#fbe9e9}.plot .barlabel{fill:#fff;font-size:10px}.plot .pointlabel{font-size:10px}\
.figure .ftitle{font-size:13px;font-weight:600;fill:#222}";

/// A mark drawn at every point of a [`Series`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    /// A dot.
    Dot,
    /// A square.
    Square,
}

/// One line of a [`LinePlot`].
#[derive(Debug, Clone)]
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Its points `(x, y)`; a non-finite y breaks the line.
    pub points: Vec<(f64, f64)>,
    /// Dashed.
    pub dashed: bool,
    /// Its colour.
    pub colour: &'static str,
    /// A mark at every point; `None`: the line alone.
    pub marker: Option<Marker>,
    /// A label beside each point, in order (points past the last label have none).
    pub labels: Vec<String>,
}

impl Series {
    /// A solid line through `points`, without marks or labels.
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>, colour: &'static str) -> Self {
        Self { name: name.into(), points, dashed: false, colour, marker: None, labels: Vec::new() }
    }
}

/// A horizontal reference line (τ, a bound).
#[derive(Debug, Clone)]
pub struct Level {
    /// Its value.
    pub y: f64,
    /// Its label.
    pub label: String,
}

/// A plot of lines over a common x axis.
#[derive(Debug, Clone)]
pub struct LinePlot {
    /// Title above the plot.
    pub title: String,
    /// x-axis label with its unit.
    pub x_label: String,
    /// y-axis label with its unit.
    pub y_label: String,
    /// The lines.
    pub series: Vec<Series>,
    /// Reference lines.
    pub levels: Vec<Level>,
    /// Fixed y range; `None`: from the data (and the levels).
    pub y_range: Option<(f64, f64)>,
    /// Fixed x range; `None`: from the data.
    pub x_range: Option<(f64, f64)>,
    /// A time cursor the report's slider moves (`class="cursor"`), for plots over the run's time.
    pub cursor: bool,
    /// Draw points, not lines (a scatter plot).
    pub markers: bool,
}

/// The plot area of every plot, px.
pub const WIDTH: f64 = 520.0;
const HEIGHT: f64 = 230.0;
const LEFT: f64 = 58.0;
const RIGHT: f64 = 12.0;
const TOP: f64 = 26.0;
const BOTTOM: f64 = 40.0;

/// Data → pixel mapping of one plot.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    left: f64,
    x: (f64, f64),
    y: (f64, f64),
    width: f64,
    height: f64,
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x.0) / (self.x.1 - self.x.0) * (self.width - self.left - RIGHT)
    }
    fn py(&self, y: f64) -> f64 {
        self.height
            - BOTTOM
            - (y.clamp(self.y.0, self.y.1) - self.y.0) / (self.y.1 - self.y.0) * (self.height - TOP - BOTTOM)
    }
}

fn padded(lo: f64, hi: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        return (lo - 1.0, hi + 1.0);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Opens a plot's `<svg>` of `width` × `height` px with its title (tooltip and heading).
fn open(s: &mut String, classes: &str, width: f64, height: f64, data: &str, title: &str) {
    let _ = write!(
        s,
        "<svg class=\"{classes}\" width=\"{width:.0}\" height=\"{height:.0}\" viewBox=\"0 0 {width:.0} {height:.0}\" role=\"img\"{data}>\
         <title>{0}</title><text class=\"ptitle\" x=\"{LEFT}\" y=\"16\">{0}</text>",
        esc(title)
    );
}

/// The vertical grid lines of `f` at round values down to `bottom`, with their labels below.
fn x_lines(s: &mut String, f: &Frame, bottom: f64) {
    let xt = ticks(f.x.0, f.x.1, 6);
    let step = xt.get(1).zip(xt.first()).map_or(1.0, |(b, a)| b - a);
    for x in &xt {
        let px = f.px(*x);
        let _ = write!(
            s,
            "<line x1=\"{px:.1}\" y1=\"{TOP}\" x2=\"{px:.1}\" y2=\"{bottom:.1}\"/><text class=\"tick\" x=\"{px:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            bottom + 14.0,
            tick_label(*x, step)
        );
    }
}

/// The horizontal grid lines of `f` at round values, with their labels on the left.
fn y_lines(s: &mut String, f: &Frame) {
    let yt = ticks(f.y.0, f.y.1, 5);
    let step = yt.get(1).zip(yt.first()).map_or(1.0, |(b, a)| b - a);
    for y in &yt {
        let py = f.py(*y);
        let _ = write!(
            s,
            "<line x1=\"{:.1}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\"/><text class=\"tick\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            f.left,
            f.width - RIGHT,
            f.left - 4.0,
            py + 4.0,
            tick_label(*y, step)
        );
    }
}

/// The axes, grid, tick labels and axis labels, in the opened `<svg …>`.
fn axes(s: &mut String, f: &Frame, title: &str, x_label: &str, y_label: &str, class: &str, data: &str) {
    let (w, h) = (f.width, f.height);
    open(s, &format!("plot {class}"), w, h, data, title);
    let _ = write!(s, "<g class=\"grid\">");
    x_lines(s, f, h - BOTTOM);
    y_lines(s, f);
    let _ = write!(
        s,
        "</g><rect class=\"frame\" x=\"{LEFT}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{:.1}\"/>\
         <text class=\"axis\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\
         <text class=\"axis\" transform=\"translate(13 {:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>",
        w - LEFT - RIGHT,
        h - TOP - BOTTOM,
        LEFT + (w - LEFT - RIGHT) / 2.0,
        h - 6.0,
        esc(x_label),
        TOP + (h - TOP - BOTTOM) / 2.0,
        esc(y_label)
    );
}

/// The time cursor's data attributes: where t = x0 and t = x1 are in pixels.
fn cursor_data(f: &Frame) -> String {
    format!(
        " data-x0=\"{}\" data-x1=\"{}\" data-px0=\"{:.2}\" data-px1=\"{:.2}\"",
        f.x.0,
        f.x.1,
        f.px(f.x.0),
        f.px(f.x.1)
    )
}

fn cursor(s: &mut String, f: &Frame) {
    let _ = write!(
        s,
        "<line class=\"cursor\" x1=\"{0:.1}\" y1=\"{TOP}\" x2=\"{0:.1}\" y2=\"{1:.1}\"/>",
        f.px(f.x.0),
        f.height - BOTTOM
    );
}

/// One entry of a plot's legend.
struct LegendItem<'a> {
    name: &'a str,
    colour: &'a str,
    dashed: bool,
    /// A line sample (the series is drawn as a line).
    line: bool,
    marker: Option<Marker>,
}

fn legend(s: &mut String, f: &Frame, items: &[LegendItem<'_>]) {
    let mut x = LEFT + 6.0;
    let y = TOP + 12.0;
    for item in items {
        let c = item.colour;
        if item.line {
            let dash = if item.dashed { " stroke-dasharray=\"5 3\"" } else { "" };
            let _ = write!(
                s,
                "<line x1=\"{x:.1}\" y1=\"{0:.1}\" x2=\"{1:.1}\" y2=\"{0:.1}\" stroke=\"{c}\" stroke-width=\"2\"{dash}/>",
                y - 4.0,
                x + 16.0,
            );
        }
        if let Some(m) = item.marker {
            mark(s, m, x + 8.0, y - 4.0, c);
        }
        let _ = write!(s, "<text class=\"legend\" x=\"{:.1}\" y=\"{y:.1}\">{}</text>", x + 20.0, esc(item.name));
        x += 30.0 + 6.2 * item.name.chars().count() as f64;
        if x > f.width - 60.0 {
            break;
        }
    }
}

/// A marker centred on `(px, py)`, px.
fn mark(s: &mut String, m: Marker, px: f64, py: f64, colour: &str) {
    let _ = match m {
        Marker::Dot => write!(s, "<circle cx=\"{px:.1}\" cy=\"{py:.1}\" r=\"3\" fill=\"{colour}\"/>"),
        Marker::Square => {
            write!(s, "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"7\" height=\"7\" fill=\"{colour}\"/>", px - 3.5, py - 3.5)
        }
    };
}

/// One series in the frame `f`: its line (none in a scatter plot, `points_only`), its markers and
/// its point labels.
fn series(s: &mut String, f: &Frame, se: &Series, points_only: bool) {
    let inside = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite() && p.0 >= f.x.0 && p.0 <= f.x.1;
    if points_only {
        for (px, py) in se.points.iter().filter(inside) {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3.5\" fill=\"{}\" fill-opacity=\"0.8\"><title>{}: {px:.2}, {py:.3}</title></circle>",
                f.px(*px),
                f.py(*py),
                se.colour,
                esc(&se.name)
            );
        }
        return;
    }
    let mut d = String::new();
    let mut pen = false;
    for (px, py) in &se.points {
        if !inside(&&(*px, *py)) {
            pen = false;
            continue;
        }
        let _ = write!(d, "{}{:.1} {:.1}", if pen { " L" } else { " M" }, f.px(*px), f.py(*py));
        pen = true;
    }
    let dash = if se.dashed { " stroke-dasharray=\"5 3\"" } else { "" };
    let _ = write!(
        s,
        "<path class=\"series\" d=\"{}\" stroke=\"{}\"{dash}><title>{}</title></path>",
        d.trim_start(),
        se.colour,
        esc(&se.name)
    );
    let labels = se.labels.iter().map(Some).chain(std::iter::repeat(None));
    for ((px, py), label) in se.points.iter().zip(labels).filter(|(p, _)| inside(p)) {
        let (x, y) = (f.px(*px), f.py(*py));
        if let Some(m) = se.marker {
            mark(s, m, x, y, se.colour);
        }
        if let Some(l) = label {
            let _ = write!(
                s,
                "<text class=\"pointlabel\" x=\"{:.1}\" y=\"{:.1}\" style=\"fill:{}\">{}</text>",
                x + 4.0,
                y - 4.0,
                se.colour,
                esc(l)
            );
        }
    }
}

impl LinePlot {
    /// A plot over time `t` in seconds, with the slider's cursor.
    pub fn over_time(title: &str, y_label: &str, t_range: (f64, f64)) -> Self {
        Self {
            title: title.to_owned(),
            x_label: "time (s)".to_owned(),
            y_label: y_label.to_owned(),
            series: Vec::new(),
            levels: Vec::new(),
            y_range: None,
            x_range: Some(t_range),
            cursor: true,
            markers: false,
        }
    }

    /// The SVG.
    pub fn svg(&self, class: &str) -> String {
        let finite = |v: &f64| v.is_finite();
        let xs = self.series.iter().flat_map(|s| s.points.iter().map(|p| p.0)).filter(finite);
        let x = self.x_range.unwrap_or_else(|| {
            let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            padded(lo, hi)
        });
        let x = if x.1 - x.0 > 1e-9 { x } else { (x.0 - 1.0, x.1 + 1.0) };
        let y = self.y_range.unwrap_or_else(|| {
            let ys = self
                .series
                .iter()
                .flat_map(|s| s.points.iter().filter(|p| p.0 >= x.0 && p.0 <= x.1).map(|p| p.1))
                .chain(self.levels.iter().map(|l| l.y))
                .filter(finite);
            let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            padded(lo, hi)
        });
        let f = Frame { left: LEFT, x, y, width: WIDTH, height: HEIGHT };
        let data = if self.cursor { cursor_data(&f) } else { String::new() };
        let mut s = String::new();
        axes(&mut s, &f, &self.title, &self.x_label, &self.y_label, class, &data);
        for l in &self.levels {
            let py = f.py(l.y);
            let _ = write!(
                s,
                "<line class=\"level\" x1=\"{LEFT}\" y1=\"{py:.1}\" x2=\"{:.1}\" y2=\"{py:.1}\"/><text class=\"levellabel\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
                f.width - RIGHT,
                f.width - RIGHT - 4.0,
                py - 4.0,
                esc(&l.label)
            );
        }
        for se in &self.series {
            series(&mut s, &f, se, self.markers);
        }
        let items: Vec<LegendItem<'_>> = self
            .series
            .iter()
            .map(|se| LegendItem {
                name: &se.name,
                colour: se.colour,
                dashed: se.dashed,
                line: !self.markers && se.points.len() > 1,
                marker: if self.markers { Some(Marker::Dot) } else { se.marker },
            })
            .collect();
        legend(&mut s, &f, &items);
        if self.cursor {
            cursor(&mut s, &f);
        }
        s.push_str("</svg>");
        s
    }
}

/// Plots side by side under one title: a figure of an experiment, in a report's page ([`Figure::svg`])
/// or as a file of its own ([`Figure::file`]).
#[derive(Debug, Clone)]
pub struct Figure {
    /// The title above the plots (wrapped to the figure's width).
    pub title: String,
    /// The plots, each with its class, left to right and then down.
    pub panels: Vec<(LinePlot, String)>,
    /// Plots in a row.
    pub columns: usize,
}

/// Height of a line of a figure's title, px.
const TITLE_LINE: f64 = 17.0;

impl Figure {
    /// The figure for a report's page, whose style it takes.
    pub fn svg(&self) -> String {
        self.draw(false)
    }

    /// The figure as a file of its own: the SVG namespace, a white ground and the plots' style.
    pub fn file(&self) -> String {
        self.draw(true) + "\n"
    }

    fn draw(&self, standalone: bool) -> String {
        let columns = self.columns.clamp(1, self.panels.len().max(1));
        let rows = self.panels.len().div_ceil(columns).max(1);
        let width = WIDTH * columns as f64;
        // About 7.5 px a character of the 13 px bold title.
        let lines = wrap(&self.title, ((width - 16.0) / 7.5).max(20.0) as usize);
        let head = 8.0 + TITLE_LINE * lines.len() as f64;
        let height = head + HEIGHT * rows as f64;
        let mut s = String::new();
        let _ = write!(s, "<svg class=\"figure\"");
        if standalone {
            s.push_str(" xmlns=\"http://www.w3.org/2000/svg\" font-family=\"system-ui, sans-serif\"");
        }
        let _ = write!(
            s,
            " width=\"{width:.0}\" height=\"{height:.0}\" viewBox=\"0 0 {width:.0} {height:.0}\" role=\"img\"><title>{}</title>",
            esc(&self.title)
        );
        if standalone {
            let _ = write!(s, "<style>{CSS}</style><rect width=\"{width:.0}\" height=\"{height:.0}\" fill=\"#fff\"/>");
        }
        for (i, line) in lines.iter().enumerate() {
            let _ = write!(
                s,
                "<text class=\"ftitle\" x=\"8\" y=\"{:.1}\">{}</text>",
                4.0 + TITLE_LINE * (i + 1) as f64,
                esc(line)
            );
        }
        for (i, (plot, class)) in self.panels.iter().enumerate() {
            let (x, y) = (WIDTH * (i % columns) as f64, head + HEIGHT * (i / columns) as f64);
            let _ = write!(s, "<g transform=\"translate({x:.0} {y:.0})\">{}</g>", plot.svg(class));
        }
        s.push_str("</svg>");
        s
    }
}

/// `text` in lines of at most about `chars` characters, broken between words.
fn wrap(text: &str, chars: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split_whitespace() {
        match lines.last_mut() {
            Some(line) if line.chars().count() + 1 + word.chars().count() <= chars => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_owned()),
        }
    }
    lines
}

/// One interval of a [`Timeline`] row.
#[derive(Debug, Clone)]
pub struct Bar {
    /// Start, s.
    pub t0: f64,
    /// End, s.
    pub t1: f64,
    /// Fill.
    pub colour: &'static str,
    /// Tooltip and printed label (when it fits).
    pub label: String,
}

/// Rows of intervals over time: states (the regulator's status, the gate) and zone occupancy.
#[derive(Debug, Clone)]
pub struct Timeline {
    /// Title above.
    pub title: String,
    /// Rows: a label and its bars.
    pub rows: Vec<(String, Vec<Bar>)>,
    /// Time range, s.
    pub t_range: (f64, f64),
    /// Gaps to mark with a bracket between two rows' bars: `(t0, t1, label)`.
    pub gaps: Vec<(f64, f64, String)>,
    /// Legend: colour and meaning.
    pub legend: Vec<(&'static str, String)>,
}

const ROW_H: f64 = 22.0;
/// Room for the row labels of a timeline, px.
const TIMELINE_LEFT: f64 = 120.0;

impl Timeline {
    /// The SVG.
    pub fn svg(&self, class: &str) -> String {
        let gap_h = if self.gaps.is_empty() { 0.0 } else { 24.0 };
        let legend_h = if self.legend.is_empty() { 0.0 } else { 18.0 };
        let height = TOP + self.rows.len() as f64 * (ROW_H + 6.0) + gap_h + legend_h + 32.0;
        let x =
            if self.t_range.1 - self.t_range.0 > 1e-9 { self.t_range } else { (self.t_range.0, self.t_range.0 + 1.0) };
        let f = Frame { left: TIMELINE_LEFT, x, y: (0.0, 1.0), width: WIDTH, height };
        let mut s = String::new();
        open(&mut s, &format!("plot timeline {class}"), WIDTH, height, &cursor_data(&f), &self.title);
        let bottom = TOP + self.rows.len() as f64 * (ROW_H + 6.0);
        let _ = write!(s, "<g class=\"grid\">");
        x_lines(&mut s, &f, bottom);
        let _ = write!(
            s,
            "</g><text class=\"axis\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">time (s)</text>",
            WIDTH - RIGHT,
            bottom + 27.0
        );
        for (i, (label, bars)) in self.rows.iter().enumerate() {
            let y = TOP + i as f64 * (ROW_H + 6.0);
            let _ = write!(
                s,
                "<text class=\"rowlabel\" x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text><rect class=\"rowbg\" x=\"{TIMELINE_LEFT}\" y=\"{y:.1}\" width=\"{:.1}\" height=\"{ROW_H}\"/>",
                TIMELINE_LEFT - 4.0,
                y + 15.0,
                esc(label),
                WIDTH - TIMELINE_LEFT - RIGHT
            );
            for b in bars {
                let (x0, x1) = (f.px(b.t0.max(x.0)), f.px(b.t1.min(x.1)));
                if x1 < x0 {
                    continue;
                }
                let _ = write!(
                    s,
                    "<rect class=\"bar\" x=\"{x0:.1}\" y=\"{y:.1}\" width=\"{:.1}\" height=\"{ROW_H}\" fill=\"{}\"><title>{}: {:.2}–{:.2} s</title></rect>",
                    (x1 - x0).max(0.8),
                    b.colour,
                    esc(&b.label),
                    b.t0,
                    b.t1
                );
                if x1 - x0 > 7.0 * b.label.chars().count() as f64 {
                    let _ = write!(
                        s,
                        "<text class=\"barlabel\" x=\"{:.1}\" y=\"{:.1}\">{}</text>",
                        x0 + 3.0,
                        y + 15.0,
                        esc(&b.label)
                    );
                }
            }
        }
        for (t0, t1, label) in &self.gaps {
            let (x0, x1) = (f.px(*t0), f.px(*t1));
            let y = bottom + 2.0;
            let _ = write!(
                s,
                "<g class=\"gap\"><path d=\"M{x0:.1} {:.1} V{y:.1} H{x1:.1} V{:.1}\"/><text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text></g>",
                y - 6.0,
                y - 6.0,
                (x0 + x1) / 2.0,
                y + gap_h - 6.0 + 14.0,
                esc(label)
            );
        }
        let mut lx = TIMELINE_LEFT;
        let ly = height - 8.0;
        for (c, meaning) in &self.legend {
            let _ = write!(
                s,
                "<rect x=\"{lx:.1}\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"{c}\"/><text class=\"legend\" x=\"{:.1}\" y=\"{ly:.1}\">{}</text>",
                ly - 9.0,
                lx + 13.0,
                esc(meaning)
            );
            lx += 22.0 + 6.2 * meaning.chars().count() as f64;
        }
        let _ = write!(
            s,
            "<line class=\"cursor\" x1=\"{0:.1}\" y1=\"{TOP}\" x2=\"{0:.1}\" y2=\"{bottom:.1}\"/></svg>",
            f.px(x.0)
        );
        s
    }
}

/// Quartiles (linear interpolation) of sorted values.
pub fn quartiles(sorted: &[f64]) -> Option<(f64, f64, f64)> {
    let q = |p: f64| {
        let pos = p * (sorted.len() - 1) as f64;
        let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
        let (a, b) = (sorted.get(lo)?, sorted.get(hi)?);
        Some(a + (b - a) * (pos - lo as f64))
    };
    if sorted.is_empty() {
        return None;
    }
    Some((q(0.25)?, q(0.5)?, q(0.75)?))
}

/// One column of a [`StripPlot`].
#[derive(Debug, Clone)]
pub struct Strip {
    /// Its label (may hold `\n` for two lines).
    pub label: String,
    /// The values, one dot each.
    pub values: Vec<f64>,
    /// Its colour.
    pub colour: &'static str,
    /// Its reference value (τ), drawn as a short red line; `None`: none.
    pub reference: Option<f64>,
    /// Marked as a target the VUT does not allow (drawn hatched, labelled).
    pub unreachable: bool,
}

/// Every run's value as a dot, per column, with the quartile box and the median.
#[derive(Debug, Clone)]
pub struct StripPlot {
    /// Title.
    pub title: String,
    /// y label with unit.
    pub y_label: String,
    /// Columns.
    pub strips: Vec<Strip>,
}

impl StripPlot {
    /// The SVG (wider with many columns).
    pub fn svg(&self, class: &str) -> String {
        // Wide enough for the longest label line (about 6 px a character at 11 px).
        let longest =
            self.strips.iter().flat_map(|s| s.label.split('\n')).map(|l| l.chars().count()).max().unwrap_or(0);
        let col = (6.2 * longest as f64 + 8.0).max(44.0);
        let width = (LEFT + RIGHT + col * self.strips.len() as f64).max(WIDTH);
        let height = HEIGHT + 40.0;
        let all =
            self.strips.iter().flat_map(|s| s.values.iter().copied().chain(s.reference)).filter(|v| v.is_finite());
        let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        let f = Frame {
            left: LEFT,
            x: (0.0, self.strips.len().max(1) as f64),
            y: padded(lo.min(0.0), hi),
            width,
            height: height - 40.0,
        };
        let mut s = String::new();
        open(&mut s, &format!("plot strip {class}"), width, height, "", &self.title);
        let _ = write!(s, "<g class=\"grid\">");
        y_lines(&mut s, &f);
        let _ = write!(
            s,
            "</g><text class=\"axis\" transform=\"translate(13 {:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>",
            TOP + (f.height - TOP - BOTTOM) / 2.0,
            esc(&self.y_label)
        );
        for (i, st) in self.strips.iter().enumerate() {
            let cx = f.px(i as f64 + 0.5);
            let mut sorted: Vec<f64> = st.values.iter().copied().filter(|v| v.is_finite()).collect();
            sorted.sort_by(f64::total_cmp);
            let _ = write!(
                s,
                "<g class=\"col\"><title>{}: {} runs</title>",
                esc(&st.label.replace('\n', " ")),
                sorted.len()
            );
            if st.unreachable {
                let _ = write!(
                    s,
                    "<rect class=\"unreachable\" x=\"{:.1}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{:.1}\"/>",
                    cx - col / 2.0 + 2.0,
                    col - 4.0,
                    f.height - TOP - BOTTOM
                );
            }
            if let Some((q1, med, q3)) = quartiles(&sorted) {
                let _ = write!(
                    s,
                    "<rect class=\"box\" x=\"{:.1}\" y=\"{:.1}\" width=\"22\" height=\"{:.1}\"/>\
                     <line class=\"median\" x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\"/>",
                    cx - 11.0,
                    f.py(q3),
                    (f.py(q1) - f.py(q3)).max(1.0),
                    cx - 11.0,
                    f.py(med),
                    cx + 11.0,
                    f.py(med)
                );
            }
            if let Some(r) = st.reference {
                let _ = write!(
                    s,
                    "<line class=\"reference\" x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\"/>",
                    cx - 18.0,
                    f.py(r),
                    cx + 18.0,
                    f.py(r)
                );
            }
            for (k, v) in sorted.iter().enumerate() {
                // A deterministic spread so that equal values stay visible.
                let dx = ((k * 7919) % 13) as f64 - 6.0;
                let _ = write!(
                    s,
                    "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.4\" fill=\"{}\" fill-opacity=\"0.75\"/>",
                    cx + dx,
                    f.py(*v),
                    st.colour
                );
            }
            for (line, text) in st.label.split('\n').enumerate() {
                let _ = write!(
                    s,
                    "<text class=\"tick\" x=\"{cx:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
                    f.height - BOTTOM + 14.0 + 12.0 * line as f64,
                    esc(text)
                );
            }
            if st.unreachable {
                let _ = write!(
                    s,
                    "<text class=\"tick warn\" x=\"{cx:.1}\" y=\"{:.1}\" text-anchor=\"middle\">not allowed</text>",
                    f.height - BOTTOM + 40.0
                );
            }
            s.push_str("</g>");
        }
        let _ = write!(
            s,
            "<rect class=\"frame\" x=\"{LEFT}\" y=\"{TOP}\" width=\"{:.1}\" height=\"{:.1}\"/></svg>",
            width - LEFT - RIGHT,
            f.height - TOP - BOTTOM
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn ticks_are_round_ordered_and_cover_the_range(lo in -1e4f64..1e4, span in 1e-3f64..1e4) {
            let hi = lo + span;
            let t = ticks(lo, hi, 6);
            prop_assert!(!t.is_empty() && t.len() <= 16, "{t:?}");
            prop_assert!(t.windows(2).all(|w| w[1] > w[0]));
            prop_assert!(t.iter().all(|v| *v >= lo - span * 1e-9 && *v <= hi + span * 1e-6), "{t:?} in [{lo}, {hi}]");
        }
    }

    #[test]
    fn quartiles_of_known_values() {
        assert_eq!(quartiles(&[1.0, 2.0, 3.0, 4.0, 5.0]), Some((2.0, 3.0, 4.0)));
        assert_eq!(quartiles(&[]), None);
        assert_eq!(quartiles(&[7.0]), Some((7.0, 7.0, 7.0)));
    }

    #[test]
    fn a_plot_labels_its_axes_and_breaks_at_missing_values() {
        let mut p = LinePlot::over_time("speed", "speed (m/s)", (0.0, 10.0));
        p.series.push(Series::line("VUT", vec![(0.0, 1.0), (1.0, f64::NAN), (2.0, 3.0), (3.0, 4.0)], colour(0)));
        let svg = p.svg("speed");
        assert!(svg.contains(">time (s)<") && svg.contains(">speed (m/s)<"), "{svg}");
        assert!(svg.contains("d=\"M") && svg.matches(" M").count() == 1, "the NaN must start a new stroke: {svg}");
        assert!(svg.contains("class=\"cursor\""));
    }

    #[test]
    fn a_figure_lays_its_plots_out_and_stands_alone_as_a_file() {
        let mut p = LinePlot::over_time("a", "x (m)", (0.0, 4.0));
        p.cursor = false;
        let mut s = Series::line("dots", vec![(1.0, 1.0), (2.0, 2.0)], colour(0));
        s.marker = Some(Marker::Dot);
        s.labels = vec!["w 1".into()];
        p.series.push(s);
        p.series.push(Series { marker: Some(Marker::Square), ..Series::line("one", vec![(3.0, 1.5)], colour(1)) });
        let fig = Figure {
            title: "A long title that has to be wrapped over more than one line of the figure, word by word, because it is \
                    far wider than the two plots side by side under it".into(),
            panels: vec![(p.clone(), "left".into()), (p.clone(), "right".into()), (p, "below".into())],
            columns: 2,
        };
        let inline = fig.svg();
        assert!(
            inline.starts_with("<svg class=\"figure\"") && !inline.contains("xmlns") && !inline.contains("<style>")
        );
        assert_eq!(inline.matches("class=\"ftitle\"").count(), 2, "{inline}");
        assert!(inline.contains(&format!("translate({WIDTH:.0} ")), "the second plot beside the first");
        assert_eq!(inline.matches("<circle").count(), 3 * (2 + 1), "a dot per point and one in the legend, per plot");
        assert!(inline.contains(">w 1</text>") && inline.matches("width=\"7\"").count() == 3 * 2);
        let file = fig.file();
        assert!(file.contains("xmlns=\"http://www.w3.org/2000/svg\"") && file.contains(CSS), "{file}");
    }
}
