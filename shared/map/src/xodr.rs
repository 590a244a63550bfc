//! OpenDRIVE 1.4–1.8 as data: the parts of the XML the lane graph needs, read with `roxmltree`
//! into plain structs. Numbers are checked (finite, lengths positive); anything a road cannot be
//! used without makes that road fail with an error naming it, and [`parse`] keeps the rest of the
//! map with a warning. Elevation, superelevation, objects and signals are not read.

use roxmltree::Node;
use serde::Serialize;

use crate::error::{MapError, MapWarning};

/// A parsed OpenDRIVE file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Document {
    /// `revMajor.revMinor` of the header.
    pub revision: (u32, u32),
    /// The header's name.
    pub name: String,
    /// The header's `<geoReference>` (a PROJ string), kept verbatim.
    pub geo_reference: Option<String>,
    /// Roads that parsed, in file order.
    pub roads: Vec<Road>,
    /// Junctions, in file order.
    pub junctions: Vec<Junction>,
}

/// Which end of a road a link touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactPoint {
    /// s = 0.
    Start,
    /// s = length.
    End,
}

/// What a road link points at.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "element", rename_all = "snake_case")]
pub enum RoadLink {
    /// Another road, at one of its ends.
    Road {
        /// Road id.
        id: String,
        /// Where on it.
        contact: ContactPoint,
    },
    /// A junction.
    Junction {
        /// Junction id.
        id: String,
    },
}

/// Traffic rule of a road.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrafficRule {
    /// Right-hand traffic: right lanes (negative ids) drive along the reference line.
    Rht,
    /// Left-hand traffic: left lanes (positive ids) drive along the reference line.
    Lht,
}

/// One road.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Road {
    /// Road id.
    pub id: String,
    /// Road name.
    pub name: String,
    /// Length of the reference line, m.
    pub length: f64,
    /// The junction this road belongs to (a connecting road), if any.
    pub junction: Option<String>,
    /// Predecessor link.
    pub predecessor: Option<RoadLink>,
    /// Successor link.
    pub successor: Option<RoadLink>,
    /// Traffic rule.
    pub rule: TrafficRule,
    /// Road types along s: (s, type), e.g. `town`, `motorway`.
    pub types: Vec<(f64, String)>,
    /// Speed limits along s: (s, m/s).
    pub speed_limits: Vec<(f64, f64)>,
    /// The plan view, geometries in s order.
    pub plan_view: Vec<Geometry>,
    /// Lane offsets (cubic in ds), in s order.
    pub lane_offsets: Vec<Poly3>,
    /// Lane sections, in s order.
    pub sections: Vec<LaneSection>,
}

/// A cubic `a + b·ds + c·ds² + d·ds³` valid from `s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Poly3 {
    /// Start of validity (road s, or section-relative sOffset for widths).
    pub s: f64,
    /// Coefficients.
    pub a: f64,
    /// Coefficients.
    pub b: f64,
    /// Coefficients.
    pub c: f64,
    /// Coefficients.
    pub d: f64,
}

impl Poly3 {
    /// Value at `ds` from the start.
    pub fn at(&self, ds: f64) -> f64 {
        self.a + ds * (self.b + ds * (self.c + ds * self.d))
    }

    /// Derivative at `ds`.
    pub fn slope(&self, ds: f64) -> f64 {
        self.b + ds * (2.0 * self.c + ds * 3.0 * self.d)
    }
}

/// Value of a piecewise cubic (entries in start order) at `s`: the last entry starting at or
/// before `s`, or 0 without one.
pub fn piecewise(polys: &[Poly3], s: f64) -> f64 {
    polys.iter().rev().find(|p| p.s <= s + 1e-9).or(polys.first()).map_or(0.0, |p| p.at(s - p.s))
}

/// Slope of a piecewise cubic at `s`.
pub fn piecewise_slope(polys: &[Poly3], s: f64) -> f64 {
    polys.iter().rev().find(|p| p.s <= s + 1e-9).or(polys.first()).map_or(0.0, |p| p.slope(s - p.s))
}

/// A plan-view geometry record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Geometry {
    /// Start s on the road.
    pub s: f64,
    /// Start x, m.
    pub x: f64,
    /// Start y, m.
    pub y: f64,
    /// Start heading, rad.
    pub hdg: f64,
    /// Length, m.
    pub length: f64,
    /// The curve.
    pub kind: GeometryKind,
}

/// The curve of a geometry record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum GeometryKind {
    /// A straight line.
    Line,
    /// Constant curvature, 1/m (positive: left).
    Arc {
        /// Curvature.
        curvature: f64,
    },
    /// Clothoid with linearly changing curvature.
    Spiral {
        /// Curvature at the start.
        curv_start: f64,
        /// Curvature at the end.
        curv_end: f64,
    },
    /// Cubic `v(u)` in the local frame (deprecated in 1.6, still read).
    Poly3 {
        /// Coefficients.
        a: f64,
        /// Coefficients.
        b: f64,
        /// Coefficients.
        c: f64,
        /// Coefficients.
        d: f64,
    },
    /// Parametric cubics `u(p)`, `v(p)` in the local frame.
    ParamPoly3 {
        /// u coefficients a, b, c, d.
        u: [f64; 4],
        /// v coefficients a, b, c, d.
        v: [f64; 4],
        /// `p ∈ [0, length]` (arcLength) or `[0, 1]` (normalized).
        normalized: bool,
    },
}

/// A lane section.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LaneSection {
    /// Start s on the road.
    pub s: f64,
    /// Left lanes (positive ids), ordered by id from 1 outward.
    pub left: Vec<Lane>,
    /// Right lanes (negative ids), ordered by id from -1 outward.
    pub right: Vec<Lane>,
    /// Road marks of the centre lane (id 0), by sOffset.
    pub center_marks: Vec<RoadMark>,
}

/// A lane of a section.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Lane {
    /// Lane id (non-zero).
    pub id: i32,
    /// OpenDRIVE lane type (`driving`, `shoulder`, `border`, `sidewalk`, `entry`, `onRamp`, …).
    pub kind: String,
    /// Predecessor lane id, in the previous section or the predecessor road.
    pub predecessor: Option<i32>,
    /// Successor lane id.
    pub successor: Option<i32>,
    /// Widths, by sOffset (relative to the section start); or outer borders (see `border`).
    pub widths: Vec<Poly3>,
    /// True when the lane is given by `<border>` (t of its outer edge) instead of `<width>`.
    pub border: bool,
    /// Road marks on the lane's outer edge, by sOffset.
    pub marks: Vec<RoadMark>,
}

impl Lane {
    /// Whether vehicles drive on it.
    pub fn is_drivable(&self) -> bool {
        matches!(
            self.kind.as_str(),
            "driving" | "entry" | "exit" | "onRamp" | "offRamp" | "connectingRamp" | "bidirectional" | "slipLane"
        )
    }
}

/// The kind of a road mark, simplified to what lane changes need.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MarkType {
    /// No mark.
    None,
    /// Solid (also `solid solid`, `curb`, `edge`: not to be crossed).
    Solid,
    /// Broken (also `broken broken`, `botts dots`: may be crossed).
    Broken,
    /// Solid on one side, broken on the other (`solid broken`, `broken solid`).
    Mixed,
}

/// A road mark from `sOffset` on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RoadMark {
    /// Start, relative to the section.
    pub s_offset: f64,
    /// Kind.
    pub kind: MarkType,
}

/// A junction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Junction {
    /// Junction id.
    pub id: String,
    /// Name.
    pub name: String,
    /// Connections.
    pub connections: Vec<Connection>,
}

/// One connection of a junction: an incoming road into a connecting road.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Connection {
    /// Connection id.
    pub id: String,
    /// The incoming road.
    pub incoming: String,
    /// The connecting road.
    pub connecting: String,
    /// Where on the connecting road the incoming road touches it.
    pub contact: ContactPoint,
    /// Lane links: (incoming lane id, connecting lane id).
    pub lane_links: Vec<(i32, i32)>,
}

fn ctx_road(id: &str) -> String {
    format!("road {id}")
}

fn attr<'a>(node: Node<'a, '_>, name: &str, context: &str) -> Result<&'a str, MapError> {
    node.attribute(name).ok_or_else(|| MapError::Missing {
        context: context.to_owned(),
        element: node.tag_name().name().to_owned(),
        attribute: name.to_owned(),
        line: line_of(node),
    })
}

fn line_of(node: Node<'_, '_>) -> u32 {
    node.document().text_pos_at(node.range().start).row
}

/// Largest magnitude any number of a map may have (coordinates, offsets, coefficients): beyond
/// projected coordinates on Earth, so a number past it is a mistake, not a place.
pub const MAX_MAGNITUDE: f64 = 1.0e8;
/// Longest road, and longest geometry of a road, m.
pub const MAX_ROAD_LENGTH_M: f64 = 100_000.0;
/// Largest gap between the end of one plan-view geometry and the start of the next, m: real maps
/// join within a centimetre (smaller gaps than this are warned about from 1 cm); a road whose
/// geometries lie metres or kilometres apart is broken, and its lanes would span the gap.
pub const MAX_PLAN_VIEW_GAP_M: f64 = 1.0;
/// Widest lane at the start of a `<width>` record, m.
pub const MAX_LANE_WIDTH_M: f64 = 100.0;

fn num(node: Node<'_, '_>, name: &str, context: &str) -> Result<f64, MapError> {
    let text = attr(node, name, context)?;
    let value: f64 = text.trim().parse().map_err(|_| MapError::Invalid {
        context: context.to_owned(),
        message: format!("<{}> {name}={text:?} is not a number (line {})", node.tag_name().name(), line_of(node)),
    })?;
    if !value.is_finite() {
        return Err(MapError::Invalid {
            context: context.to_owned(),
            message: format!("<{}> {name}={text:?} is not finite (line {})", node.tag_name().name(), line_of(node)),
        });
    }
    if value != 0.0 && value.abs() < f64::MIN_POSITIVE {
        return Err(MapError::Invalid {
            context: context.to_owned(),
            message: format!(
                "<{}> {name}={text:?} is subnormal (nonzero but below {:e}): no map means it (line {})",
                node.tag_name().name(),
                f64::MIN_POSITIVE,
                line_of(node)
            ),
        });
    }
    if value.abs() > MAX_MAGNITUDE {
        return Err(MapError::Invalid {
            context: context.to_owned(),
            message: format!(
                "<{}> {name}={text:?} lies beyond ±{MAX_MAGNITUDE:e} (line {})",
                node.tag_name().name(),
                line_of(node)
            ),
        });
    }
    Ok(value)
}

/// Shortest road or geometry that means anything, m: a millimetre. A shorter positive length
/// (down to the subnormal numbers, which pass every "> 0") is a mistake, and the curve formulas
/// divide by it.
pub const MIN_LENGTH_M: f64 = 1.0e-3;

/// A length from the map: at least [`MIN_LENGTH_M`] (or exactly 0 when `zero_ok`), at most
/// [`MAX_ROAD_LENGTH_M`].
fn length_within(length: f64, zero_ok: bool, context: &str) -> Result<f64, MapError> {
    let low_ok = length >= MIN_LENGTH_M || (zero_ok && length == 0.0);
    if low_ok && length <= MAX_ROAD_LENGTH_M {
        Ok(length)
    } else {
        let zero = if zero_ok { "0 or " } else { "" };
        Err(MapError::Invalid {
            context: context.to_owned(),
            message: format!("length {length} must be {zero}within [{MIN_LENGTH_M}, {MAX_ROAD_LENGTH_M}] m"),
        })
    }
}

fn num_or(node: Node<'_, '_>, name: &str, default: f64, context: &str) -> Result<f64, MapError> {
    if node.has_attribute(name) { num(node, name, context) } else { Ok(default) }
}

fn int(node: Node<'_, '_>, name: &str, context: &str) -> Result<i32, MapError> {
    let text = attr(node, name, context)?;
    let trimmed = text.trim();
    // Some exporters write lane ids as "-1.0".
    trimmed
        .parse::<i32>()
        .ok()
        .or_else(|| trimmed.parse::<f64>().ok().filter(|v| v.fract() == 0.0).map(|v| v as i32))
        .ok_or_else(|| MapError::Invalid {
            context: context.to_owned(),
            message: format!("<{}> {name}={text:?} is not an integer (line {})", node.tag_name().name(), line_of(node)),
        })
}

fn children<'a, 'i>(node: Node<'a, 'i>, tag: &'a str) -> impl Iterator<Item = Node<'a, 'i>> + 'a {
    node.children().filter(move |c| c.is_element() && c.tag_name().name() == tag)
}

fn child<'a, 'i>(node: Node<'a, 'i>, tag: &'a str) -> Option<Node<'a, 'i>> {
    children(node, tag).next()
}

fn contact(node: Node<'_, '_>, context: &str) -> Result<ContactPoint, MapError> {
    match attr(node, "contactPoint", context)? {
        "start" => Ok(ContactPoint::Start),
        "end" => Ok(ContactPoint::End),
        other => Err(MapError::Invalid {
            context: context.to_owned(),
            message: format!("contactPoint {other:?} must be start or end (line {})", line_of(node)),
        }),
    }
}

fn road_link(node: Node<'_, '_>, context: &str) -> Result<RoadLink, MapError> {
    let id = attr(node, "elementId", context)?.to_owned();
    match node.attribute("elementType").unwrap_or("road") {
        "road" => Ok(RoadLink::Road { id, contact: contact(node, context)? }),
        "junction" => Ok(RoadLink::Junction { id }),
        other => Err(MapError::Invalid {
            context: context.to_owned(),
            message: format!("link elementType {other:?} must be road or junction (line {})", line_of(node)),
        }),
    }
}

/// Parses OpenDRIVE XML. Roads that cannot be used are left out with a warning each; the whole
/// file fails only when the XML or the header is broken, or no road is left.
pub fn parse(xml: &str) -> Result<(Document, Vec<MapWarning>), MapError> {
    let doc = roxmltree::Document::parse_with_options(
        xml,
        roxmltree::ParsingOptions { allow_dtd: true, ..Default::default() },
    )
    .map_err(|e| MapError::Xml(e.to_string()))?;
    let root = doc.root_element();
    if root.tag_name().name() != "OpenDRIVE" {
        return Err(MapError::Xml(format!("the root element is <{}>, not <OpenDRIVE>", root.tag_name().name())));
    }
    let header = child(root, "header")
        .ok_or_else(|| MapError::Invalid { context: "header".into(), message: "<OpenDRIVE> has no <header>".into() })?;
    let revision = (int(header, "revMajor", "header")?, int(header, "revMinor", "header")?);
    if revision.0 != 1 {
        return Err(MapError::Invalid {
            context: "header".into(),
            message: format!("OpenDRIVE revMajor {} is not supported (1.x only)", revision.0),
        });
    }
    let geo_reference =
        child(header, "geoReference").and_then(|g| g.text()).map(|t| t.trim().to_owned()).filter(|t| !t.is_empty());
    let mut warnings = Vec::new();
    let mut roads = Vec::new();
    for node in children(root, "road") {
        let id = node.attribute("id").unwrap_or("?").to_owned();
        let mut found = Vec::new();
        let parsed = road(node, &mut found);
        match parsed {
            Ok(r) => {
                warnings.append(&mut found);
                if roads.iter().any(|o: &Road| o.id == r.id) {
                    warnings.push(MapWarning::new(ctx_road(&id), "a second road with this id is left out"));
                } else {
                    roads.push(r);
                }
            }
            Err(e) => warnings.push(MapWarning::new(ctx_road(&id), format!("left out: {e}"))),
        }
    }
    if roads.is_empty() {
        return Err(MapError::Invalid { context: "map".into(), message: "no usable road".into() });
    }
    let mut junctions = Vec::new();
    for node in children(root, "junction") {
        let id = node.attribute("id").unwrap_or("?").to_owned();
        match junction(node, &mut warnings) {
            Ok(j) => junctions.push(j),
            Err(e) => warnings.push(MapWarning::new(format!("junction {id}"), format!("left out: {e}"))),
        }
    }
    let revision = (u32::try_from(revision.0).unwrap_or(1), u32::try_from(revision.1).unwrap_or(0));
    let name = header.attribute("name").unwrap_or_default().to_owned();
    Ok((Document { revision, name, geo_reference, roads, junctions }, warnings))
}

/// One road; what is wrong but usable (unsorted `s`, a lane of no width, a number in an element
/// this reader does not use) goes to `warnings`.
fn road(node: Node<'_, '_>, warnings: &mut Vec<MapWarning>) -> Result<Road, MapError> {
    let id = attr(node, "id", "road")?.to_owned();
    let ctx = ctx_road(&id);
    unread_numbers(node, &ctx, warnings);
    let length = length_within(num(node, "length", &ctx)?, false, &ctx)?;
    let junction = node.attribute("junction").map(str::trim).filter(|j| !j.is_empty() && *j != "-1").map(str::to_owned);
    let rule = match node.attribute("rule") {
        Some("LHT") => TrafficRule::Lht,
        _ => TrafficRule::Rht,
    };
    let (mut predecessor, mut successor) = (None, None);
    if let Some(link) = child(node, "link") {
        if let Some(p) = child(link, "predecessor") {
            predecessor = Some(road_link(p, &ctx)?);
        }
        if let Some(s) = child(link, "successor") {
            successor = Some(road_link(s, &ctx)?);
        }
    }
    let mut types = Vec::new();
    let mut speed_limits = Vec::new();
    for t in children(node, "type") {
        let s = num(t, "s", &ctx)?;
        types.push((s, t.attribute("type").unwrap_or("unknown").to_owned()));
        if let Some(speed) = child(t, "speed")
            && let Some(max) = speed.attribute("max").and_then(|m| m.trim().parse::<f64>().ok())
            && max.is_finite()
            && max > 0.0
        {
            let factor = match speed.attribute("unit").unwrap_or("m/s") {
                "km/h" => 1.0 / 3.6,
                "mph" => 0.447_04,
                _ => 1.0,
            };
            speed_limits.push((s, max * factor));
        }
    }
    let plan = child(node, "planView")
        .ok_or_else(|| MapError::Invalid { context: ctx.clone(), message: "no <planView>".into() })?;
    let mut plan_view = Vec::new();
    for g in children(plan, "geometry") {
        plan_view.push(geometry(g, &ctx)?);
    }
    if plan_view.is_empty() {
        return Err(MapError::Invalid { context: ctx, message: "<planView> has no <geometry>".into() });
    }
    if let Some(w) = plan_view.windows(2).find(|w| matches!(w, [a, b] if b.s < a.s)) {
        let (before, after) = (w.first().map_or(0.0, |g| g.s), w.get(1).map_or(0.0, |g| g.s));
        warnings.push(MapWarning::new(
            ctx.clone(),
            format!("<planView> geometries are not in increasing s (s={after} after s={before}); read in s order"),
        ));
    }
    plan_view.sort_by(|a, b| a.s.total_cmp(&b.s));
    if let Some((gap, s)) = crate::geometry::ReferenceLine::new(&plan_view).worst_gap()
        && (gap.is_nan() || gap > MAX_PLAN_VIEW_GAP_M)
    {
        return Err(MapError::Invalid {
            context: ctx,
            message: format!(
                "its plan view jumps {gap:.3} m at s = {s:.2}: geometries that do not join within {MAX_PLAN_VIEW_GAP_M} m are no road"
            ),
        });
    }
    let lanes =
        child(node, "lanes").ok_or_else(|| MapError::Invalid { context: ctx.clone(), message: "no <lanes>".into() })?;
    let mut lane_offsets = Vec::new();
    for o in children(lanes, "laneOffset") {
        lane_offsets.push(poly(o, "s", &ctx)?);
    }
    lane_offsets.sort_by(|a, b| a.s.total_cmp(&b.s));
    let mut sections: Vec<LaneSection> = Vec::new();
    for (k, sec) in children(lanes, "laneSection").enumerate() {
        let sctx = format!("{ctx} laneSection {k}");
        let section = section(sec, &sctx, warnings)?;
        if section.s < 0.0 {
            warnings.push(MapWarning::new(
                sctx,
                format!("starts at s={} before the road's start (s ≥ 0); left out (line {})", section.s, line_of(sec)),
            ));
            continue;
        }
        if let Some(last) = sections.last()
            && section.s < last.s
        {
            warnings.push(MapWarning::new(
                sctx,
                format!("at s={} after a section at s={}: not in increasing s; read in s order", section.s, last.s),
            ));
        }
        sections.push(section);
    }
    if sections.is_empty() {
        return Err(MapError::Invalid { context: ctx, message: "<lanes> has no usable <laneSection>".into() });
    }
    sections.sort_by(|a, b| a.s.total_cmp(&b.s));
    Ok(Road {
        id,
        name: node.attribute("name").unwrap_or_default().to_owned(),
        length,
        junction,
        predecessor,
        successor,
        rule,
        types,
        speed_limits,
        plan_view,
        lane_offsets,
        sections,
    })
}

fn poly(node: Node<'_, '_>, s_name: &str, ctx: &str) -> Result<Poly3, MapError> {
    Ok(Poly3 {
        s: num(node, s_name, ctx)?,
        a: num_or(node, "a", 0.0, ctx)?,
        b: num_or(node, "b", 0.0, ctx)?,
        c: num_or(node, "c", 0.0, ctx)?,
        d: num_or(node, "d", 0.0, ctx)?,
    })
}

fn geometry(g: Node<'_, '_>, ctx: &str) -> Result<Geometry, MapError> {
    let s = num(g, "s", ctx)?;
    let gctx = format!("{ctx} geometry at s={s}");
    let length = length_within(num(g, "length", &gctx)?, true, &gctx)?;
    let curve = g
        .children()
        .find(roxmltree::Node::is_element)
        .ok_or_else(|| MapError::UnknownGeometry { context: gctx.clone(), kind: "(none)".into() })?;
    let kind = match curve.tag_name().name() {
        "line" => GeometryKind::Line,
        "arc" => GeometryKind::Arc { curvature: num(curve, "curvature", &gctx)? },
        "spiral" => GeometryKind::Spiral {
            curv_start: num(curve, "curvStart", &gctx)?,
            curv_end: num(curve, "curvEnd", &gctx)?,
        },
        "poly3" => GeometryKind::Poly3 {
            a: num_or(curve, "a", 0.0, &gctx)?,
            b: num_or(curve, "b", 0.0, &gctx)?,
            c: num_or(curve, "c", 0.0, &gctx)?,
            d: num_or(curve, "d", 0.0, &gctx)?,
        },
        "paramPoly3" => {
            let mut u = [0.0; 4];
            let mut v = [0.0; 4];
            for (i, n) in ["a", "b", "c", "d"].iter().enumerate() {
                if let (Some(uu), Some(vv)) = (u.get_mut(i), v.get_mut(i)) {
                    *uu = num_or(curve, &format!("{n}U"), 0.0, &gctx)?;
                    *vv = num_or(curve, &format!("{n}V"), 0.0, &gctx)?;
                }
            }
            let normalized = match curve.attribute("pRange").unwrap_or("normalized") {
                "arcLength" => false,
                "normalized" => true,
                other => {
                    return Err(MapError::Invalid {
                        context: gctx,
                        message: format!("paramPoly3 pRange {other:?} must be arcLength or normalized"),
                    });
                }
            };
            GeometryKind::ParamPoly3 { u, v, normalized }
        }
        other => return Err(MapError::UnknownGeometry { context: gctx, kind: other.to_owned() }),
    };
    Ok(Geometry { s, x: num(g, "x", ctx)?, y: num(g, "y", ctx)?, hdg: num(g, "hdg", ctx)?, length, kind })
}

fn section(sec: Node<'_, '_>, ctx: &str, warnings: &mut Vec<MapWarning>) -> Result<LaneSection, MapError> {
    let s = num(sec, "s", ctx)?;
    let mut left = Vec::new();
    let mut right = Vec::new();
    let mut center_marks = Vec::new();
    for side in ["left", "center", "right"] {
        let Some(side_node) = child(sec, side) else { continue };
        for l in children(side_node, "lane") {
            let id = int(l, "id", ctx)?;
            let lctx = format!("{ctx} lane {id}");
            let marks = marks(l, &lctx)?;
            if side == "center" {
                center_marks = marks;
                continue;
            }
            if (side == "left") != (id > 0) || id == 0 {
                return Err(MapError::Invalid { context: lctx, message: format!("lane id {id} on the {side} side") });
            }
            let (mut predecessor, mut successor) = (None, None);
            if let Some(link) = child(l, "link") {
                if let Some(p) = child(link, "predecessor") {
                    predecessor = Some(int(p, "id", &lctx)?);
                }
                if let Some(n) = child(link, "successor") {
                    successor = Some(int(n, "id", &lctx)?);
                }
            }
            let mut widths = Vec::new();
            for w in children(l, "width") {
                let width = poly(w, "sOffset", &lctx)?;
                if width.a.abs() > MAX_LANE_WIDTH_M {
                    return Err(MapError::Invalid {
                        context: lctx,
                        message: format!(
                            "<width> a={} m lies beyond ±{MAX_LANE_WIDTH_M} m (line {})",
                            width.a,
                            line_of(w)
                        ),
                    });
                }
                widths.push(width);
            }
            let border = widths.is_empty();
            if border {
                for b in children(l, "border") {
                    widths.push(poly(b, "sOffset", &lctx)?);
                }
            }
            if widths.is_empty() {
                return Err(MapError::Invalid {
                    context: lctx,
                    message: "lane has neither <width> nor <border>".into(),
                });
            }
            widths.sort_by(|a, b| a.s.total_cmp(&b.s));
            if !border
                && let Some(w) = widths.iter().find(|w| w.a <= 0.0)
                && l.attribute("type").is_some_and(|t| t.trim() != "none")
            {
                warnings.push(MapWarning::new(
                    lctx.clone(),
                    format!(
                        "<width> at sOffset {} starts at a={} m, not a positive width: the lane is not drivable there",
                        w.s, w.a
                    ),
                ));
            }
            let lane = Lane {
                id,
                kind: l.attribute("type").unwrap_or("none").to_owned(),
                predecessor,
                successor,
                widths,
                border,
                marks,
            };
            if id > 0 { left.push(lane) } else { right.push(lane) }
        }
    }
    left.sort_by_key(|l| l.id);
    right.sort_by_key(|l| -l.id);
    for (side, lanes, sign) in [("left", &left, 1), ("right", &right, -1)] {
        for (k, lane) in lanes.iter().enumerate() {
            let expected = sign * i32::try_from(k + 1).unwrap_or(i32::MAX);
            if lane.id != expected {
                return Err(MapError::Invalid {
                    context: ctx.to_owned(),
                    message: format!(
                        "{side} lane ids must run {sign}, {}, … without gaps; found {}",
                        2 * sign,
                        lane.id
                    ),
                });
            }
        }
    }
    Ok(LaneSection { s, left, right, center_marks })
}

/// Elements of a road this reader does not use (elevation, lateral profile, objects, signals):
/// a number there that is not a finite, normal number still makes the map wrong, so it is named.
fn unread_numbers(road: Node<'_, '_>, ctx: &str, warnings: &mut Vec<MapWarning>) {
    const UNREAD: [&str; 4] = ["elevationProfile", "lateralProfile", "objects", "signals"];
    const TEXT: [&str; 6] = ["id", "name", "type", "subtype", "country", "orientation"];
    for part in road.children().filter(|n| n.is_element() && UNREAD.contains(&n.tag_name().name())) {
        for n in part.descendants().filter(roxmltree::Node::is_element) {
            for a in n.attributes().filter(|a| !TEXT.contains(&a.name())) {
                let Ok(x) = a.value().trim().parse::<f64>() else { continue };
                if !x.is_finite() || (x != 0.0 && x.abs() < f64::MIN_POSITIVE) {
                    warnings.push(MapWarning::new(
                        ctx.to_owned(),
                        format!(
                            "<{}> {}={:?} is not a finite normal number (line {}); this reader does not use <{}>, \
                             but the map is wrong",
                            n.tag_name().name(),
                            a.name(),
                            a.value(),
                            line_of(n),
                            part.tag_name().name()
                        ),
                    ));
                }
            }
        }
    }
}

fn marks(lane: Node<'_, '_>, ctx: &str) -> Result<Vec<RoadMark>, MapError> {
    let mut out = Vec::new();
    for m in children(lane, "roadMark") {
        let kind = match m.attribute("type").unwrap_or("none").trim() {
            "solid" | "solid solid" | "curb" | "edge" | "grass" => MarkType::Solid,
            "broken" | "broken broken" | "botts dots" => MarkType::Broken,
            "solid broken" | "broken solid" => MarkType::Mixed,
            _ => MarkType::None,
        };
        out.push(RoadMark { s_offset: num_or(m, "sOffset", 0.0, ctx)?, kind });
    }
    out.sort_by(|a, b| a.s_offset.total_cmp(&b.s_offset));
    Ok(out)
}

fn junction(node: Node<'_, '_>, warnings: &mut Vec<MapWarning>) -> Result<Junction, MapError> {
    let id = attr(node, "id", "junction")?.to_owned();
    let ctx = format!("junction {id}");
    let mut connections = Vec::new();
    for c in children(node, "connection") {
        let cid = c.attribute("id").unwrap_or("?");
        let cctx = format!("{ctx} connection {cid}");
        let parsed = (|| -> Result<Connection, MapError> {
            let mut lane_links = Vec::new();
            for l in children(c, "laneLink") {
                lane_links.push((int(l, "from", &cctx)?, int(l, "to", &cctx)?));
            }
            Ok(Connection {
                id: cid.to_owned(),
                incoming: attr(c, "incomingRoad", &cctx)?.to_owned(),
                connecting: attr(c, "connectingRoad", &cctx)?.to_owned(),
                contact: contact(c, &cctx)?,
                lane_links,
            })
        })();
        match parsed {
            Ok(conn) => connections.push(conn),
            Err(e) => warnings.push(MapWarning::new(cctx.clone(), format!("left out: {e}"))),
        }
    }
    Ok(Junction { id, name: node.attribute("name").unwrap_or_default().to_owned(), connections })
}
