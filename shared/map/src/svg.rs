//! An SVG drawing of a map and its topology library: lane surfaces, boundaries with their marks
//! (solid, dashed), maneuver paths of every fragment, and anchors coloured by kind, with ids as
//! tooltips. Track frame with y up.

use std::fmt::Write;

use v2t_model::geometry::Point2;
use v2t_model::text::xml_escape;

use crate::Map;
use crate::library::{AnchorKind, FragmentKind, TopologyLibrary};
use crate::xodr::MarkType;

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

/// The drawing, as SVG text.
pub fn render(map: &Map, lib: &TopologyLibrary) -> String {
    let pts = map.graph.lanes.iter().flat_map(|l| l.samples.iter().flat_map(|q| [q.left, q.right]));
    let (x0, y0, x1, y1) = pts.fold((f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY), |b, p| {
        (b.0.min(p.x), b.1.min(p.y), b.2.max(p.x), b.3.max(p.y))
    });
    let (x0, y0, x1, y1) =
        if x0.is_finite() { (x0 - 10.0, y0 - 10.0, x1 + 10.0, y1 + 10.0) } else { (0.0, 0.0, 1.0, 1.0) };
    let (w, h) = (x1 - x0, y1 - y0);
    let scale = (1600.0 / w.max(h)).min(8.0);
    let tx = |p: Point2| ((p.x - x0) * scale, (y1 - p.y) * scale);
    let path = |points: &mut dyn Iterator<Item = Point2>| {
        let mut d = String::new();
        for (i, p) in points.enumerate() {
            let (x, y) = tx(p);
            let _ = write!(d, "{}{x:.2},{y:.2} ", if i == 0 { "M" } else { "L" });
        }
        d
    };
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{:.0}" height="{:.0}" viewBox="0 0 {:.0} {:.0}">"#,
        w * scale,
        h * scale,
        w * scale,
        h * scale
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="#f8f9fa"/>"##);
    let _ = writeln!(s, "<title>{}</title>", xml_escape(&map.name));
    // Lane surfaces.
    let _ = writeln!(s, r#"<g id="lanes">"#);
    for l in &map.graph.lanes {
        if l.samples.len() < 2 {
            continue;
        }
        let outline: Vec<Point2> =
            l.samples.iter().map(|q| q.left).chain(l.samples.iter().rev().map(|q| q.right)).collect();
        let fill = if l.drivable { "#c9cdd2" } else { "#e3e5e8" };
        let _ = writeln!(
            s,
            r#"<path d="{}Z" fill="{fill}" stroke="none"><title>{} ({})</title></path>"#,
            path(&mut outline.into_iter()),
            l.key,
            xml_escape(&l.kind)
        );
    }
    let _ = writeln!(s, "</g>");
    // Boundaries by mark, split where the mark changes.
    let _ = writeln!(s, r#"<g id="marks" fill="none" stroke-width="1">"#);
    for l in &map.graph.lanes {
        for side in [true, false] {
            let mut run: Vec<Point2> = Vec::new();
            let mut kind = None;
            let flush = |s: &mut String, run: &[Point2], kind: Option<MarkType>| {
                let dash = match kind {
                    Some(MarkType::Broken) => r#" stroke-dasharray="6 6""#,
                    Some(MarkType::Mixed) => r#" stroke-dasharray="12 3""#,
                    _ => "",
                };
                if run.len() >= 2 && !matches!(kind, Some(MarkType::None) | None) {
                    let _ = writeln!(s, r##"<path d="{}" stroke="#ffffff"{dash}/>"##, path(&mut run.iter().copied()));
                }
            };
            for q in &l.samples {
                let (p, m) = if side { (q.left, q.left_mark) } else { (q.right, q.right_mark) };
                if kind != Some(m) {
                    if let Some(last) = run.last().copied() {
                        flush(&mut s, &run, kind);
                        run = vec![last];
                    }
                    kind = Some(m);
                }
                run.push(p);
            }
            flush(&mut s, &run, kind);
        }
    }
    let _ = writeln!(s, "</g>");
    // Fragments: maneuver paths and anchors.
    for f in &lib.fragments {
        let _ = writeln!(s, r#"<g id="{}" class="fragment">"#, xml_escape(&f.id));
        let _ = writeln!(s, "<title>{}</title>", xml_escape(&f.description));
        for m in &f.maneuvers {
            let _ = writeln!(
                s,
                r#"<path d="{}" fill="none" stroke="{}" stroke-width="1" opacity="0.6"><title>{}</title></path>"#,
                path(&mut m.path.iter().copied()),
                fragment_colour(f.kind),
                xml_escape(&m.id)
            );
        }
        for a in &f.anchors {
            let (x, y) = tx(a.position);
            let _ = writeln!(
                s,
                r#"<circle cx="{x:.2}" cy="{y:.2}" r="3" fill="{}"><title>{}</title></circle>"#,
                colour(a.kind),
                xml_escape(&a.id)
            );
        }
        let (x, y) = tx(f.centre);
        let _ = writeln!(
            s,
            r#"<text x="{x:.1}" y="{y:.1}" font-family="sans-serif" font-size="12" fill="{}">{}</text>"#,
            fragment_colour(f.kind),
            xml_escape(f.name.as_deref().unwrap_or(&f.id))
        );
        let _ = writeln!(s, "</g>");
    }
    let _ = writeln!(s, "</svg>");
    s
}

