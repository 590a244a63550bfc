#!/usr/bin/env python3
"""Generate the Video2Track proving ground, config/maps/proving_ground.xodr (ASAM OpenDRIVE 1.7).

    python3 config/maps/proving_ground.py            # rewrites proving_ground.xodr beside this file
    python3 config/maps/proving_ground.py --check    # builds and checks, fails if the file differs

Standard library only, deterministic: the same Python on the same machine writes the same bytes.
Every number in the file is computed here — lines and arcs in closed form, clothoids and
paramPoly3 lengths by composite Gauss-Legendre quadrature (error far below a nanometre) — and
nothing is written unless the file, read back from its own text, passes the checks in `verify`:
geometry s-coordinates consecutive and summing to the road length; every geometry starting where
the previous one ends (position 1e-9 m, heading 1e-12 rad); curvature continuous along every road
(clothoid-arc-clothoid corners); every road link and every junction connection joining reference
lines end to end (1e-6 m, 1e-9 rad; junction connecting roads run from reference line to reference
line, lanes placed with <laneOffset>); the inner edge, centre and outer edge of every linked pair of
lanes coinciding (1e-6 m); the lane graph strongly connected (every lane can be driven forever and
reached from every other) with a successor for every driving lane except the one that tapers to
zero width; the on-ramp clear of the main carriageway outside the junctions.

Layout (x east, y north, metres; right-hand traffic, 3.5 m lanes, 2 lanes each way on the loop):
a figure eight crossing itself at the 4-arm intersection, junction 100, at the origin. The
north-east lobe, road 1, leaves the intersection eastwards and comes back from the north; the
south-west lobe leaves southwards (road 2, the diverge junction 200, road 3 around the south-east
corner, the merge junction 300, road 5 with the 3-lane straight and its lane drop, road 6 around
the two western corners) and comes back from the west. The on-ramp, road 4, leaves road 2's outer
lane at junction 200, cuts across the south-east corner inside the lobe, and joins road 5 at
junction 300 as its third lane, which ends after the straight with a cubic taper to zero width.
"""

from __future__ import annotations

import math
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path as FilePath

HERE = FilePath(__file__).resolve().parent
OUTPUT = HERE / "proving_ground.xodr"

# ----------------------------------------------------------------------------------------------
# Design parameters
# ----------------------------------------------------------------------------------------------

LANE_W = 3.5  # every driving lane, m
A = 25.0  # the intersection's half size: its arms start 25 m from the centre, m

# North-east lobe (road 1): a 500 m x 500 m rectangle with rounded corners.
LOBE_A = 500.0
LOBE_A_R, LOBE_A_LS = 120.0, 50.0  # corner radius, clothoid length, m

# South-west lobe: 1100 m x 500 m.
LOBE_B_W, LOBE_B_H = 1150.0, 500.0
LOBE_B_R, LOBE_B_LS = 150.0, 60.0

# Diverge (junction 200) on the southward arm, merge (junction 300) on the westward bottom side.
J2_TOP = -110.0  # y of the diverge junction's upstream edge
JL = 80.0  # length of the diverge and merge junctions along the carriageway, m
GAP = 3.0  # clear gap between the ramp lane and the main carriageway outside the junctions, m
X3 = -280.0  # x of the merge junction's upstream edge

# On-ramp (road 4): south, 45 deg right, diagonal, 45 deg right, west.
RAMP_D = 180.0  # distance of the diagonal's corners from the corner of the ramp's straight lines, m
RAMP_R, RAMP_LS = 100.0, 30.0

# Road 5: the 3-lane straight, then the lane drop.
L_3LANE = 420.0
L_TAPER = 100.0

# Turns inside the intersection (reference lines; lanes lie beside them).
TURN_R, TURN_LS = 20.0, 8.0

SPEED_MAIN, SPEED_RAMP, SPEED_TURN, SPEED_CROSS = 60, 50, 30, 50  # km/h

GEO_REFERENCE = (
    "+proj=tmerc +lat_0=48.0 +lon_0=11.0 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +datum=WGS84 +units=m +no_defs"
)
MAP_DATE = "2026-11-22T00:00:00"

TOL_POS = 1e-6  # m: road ends, lane edges across every link
TOL_HDG = 1e-9  # rad

# ----------------------------------------------------------------------------------------------
# Numerics
# ----------------------------------------------------------------------------------------------

_GL_A = math.sqrt(5.0 - 2.0 * math.sqrt(10.0 / 7.0)) / 3.0
_GL_B = math.sqrt(5.0 + 2.0 * math.sqrt(10.0 / 7.0)) / 3.0
_GL_WA = (322.0 + 13.0 * math.sqrt(70.0)) / 900.0
_GL_WB = (322.0 - 13.0 * math.sqrt(70.0)) / 900.0
GL5 = ((-_GL_B, _GL_WB), (-_GL_A, _GL_WA), (0.0, 128.0 / 225.0), (_GL_A, _GL_WA), (_GL_B, _GL_WB))


def integrate(f, a: float, b: float, panel: float = 1.0):
    """Composite 5-point Gauss-Legendre of f over [a, b]; f returns a tuple of floats."""
    if b <= a:
        return None
    n = max(4, math.ceil((b - a) / panel))
    h = (b - a) / n
    acc = None
    for i in range(n):
        mid = a + (i + 0.5) * h
        for xi, wi in GL5:
            val = f(mid + 0.5 * h * xi)
            w = 0.5 * h * wi
            acc = [w * v for v in val] if acc is None else [s + w * v for s, v in zip(acc, val)]
    return acc


def wrap(a: float) -> float:
    """Angle in (-pi, pi]."""
    a = math.fmod(a, 2.0 * math.pi)
    if a <= -math.pi:
        a += 2.0 * math.pi
    elif a > math.pi:
        a -= 2.0 * math.pi
    return a


def fmt_pos(v: float) -> str:
    """Positions and lengths: 1e-10 m resolution."""
    s = f"{v:.10f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def fmt_num(v: float) -> str:
    """Headings, curvatures, coefficients: 15 significant digits."""
    if v == 0.0:
        return "0"
    s = f"{v:.15g}"
    return "0" if s == "-0" else s


# ----------------------------------------------------------------------------------------------
# Geometry
# ----------------------------------------------------------------------------------------------


class Geom:
    """One <geometry> record: line, arc, spiral or paramPoly3 (pRange normalized)."""

    def __init__(self, kind: str, x: float, y: float, hdg: float, length: float, **p):
        self.kind, self.x, self.y, self.hdg, self.length, self.p = kind, x, y, hdg, length, p
        self.s = 0.0

    def _ppoly(self, q: float):
        u, v = self.p["u"], self.p["v"]
        return (
            u[0] + q * (u[1] + q * (u[2] + q * u[3])),
            v[0] + q * (v[1] + q * (v[2] + q * v[3])),
            u[1] + q * (2 * u[2] + 3 * q * u[3]),
            v[1] + q * (2 * v[2] + 3 * q * v[3]),
            2 * u[2] + 6 * q * u[3],
            2 * v[2] + 6 * q * v[3],
        )

    def curvature(self, ds: float) -> float:
        if self.kind == "line":
            return 0.0
        if self.kind == "arc":
            return self.p["k"]
        if self.kind == "spiral":
            k0, k1 = self.p["k0"], self.p["k1"]
            return k0 + (k1 - k0) * ds / self.length
        _, _, du, dv, ddu, ddv = self._ppoly(ds / self.length)
        return (du * ddv - dv * ddu) / (du * du + dv * dv) ** 1.5 / self.length

    def pose(self, ds: float):
        """(x, y, hdg) at ds from the geometry's start."""
        x0, y0, h0 = self.x, self.y, self.hdg
        if self.kind == "line":
            return x0 + ds * math.cos(h0), y0 + ds * math.sin(h0), h0
        if self.kind == "arc":
            k = self.p["k"]
            h = h0 + k * ds
            return x0 + (math.sin(h) - math.sin(h0)) / k, y0 - (math.cos(h) - math.cos(h0)) / k, h
        if self.kind == "spiral":
            k0, c = self.p["k0"], (self.p["k1"] - self.p["k0"]) / self.length

            def head(s):
                return h0 + s * (k0 + 0.5 * c * s)

            if ds <= 0.0:
                return x0, y0, h0
            dx, dy = integrate(lambda s: (math.cos(head(s)), math.sin(head(s))), 0.0, ds, 1.0)
            return x0 + dx, y0 + dy, head(ds)
        u, v, du, dv, _, _ = self._ppoly(ds / self.length)
        c, s = math.cos(h0), math.sin(h0)
        return x0 + u * c - v * s, y0 + u * s + v * c, h0 + math.atan2(dv, du)

    def end(self):
        return self.pose(self.length)


def ppoly_length(u, v) -> float:
    def speed(q):
        du = u[1] + q * (2 * u[2] + 3 * q * u[3])
        dv = v[1] + q * (2 * v[2] + 3 * q * v[3])
        return (math.hypot(du, dv),)

    return integrate(speed, 0.0, 1.0, 1.0 / 256.0)[0]


class RefLine:
    """A reference line built piece by piece from a start pose."""

    def __init__(self, x: float, y: float, hdg: float):
        self.geoms: list[Geom] = []
        self.pose = (x, y, hdg)
        self.s = 0.0

    def _add(self, g: Geom):
        g.s = self.s
        self.geoms.append(g)
        self.s += g.length
        self.pose = g.end()

    def line(self, length: float):
        assert length > 1e-6, f"line of length {length}"
        self._add(Geom("line", *self.pose, length))

    def arc(self, k: float, length: float):
        assert length > 1e-6
        self._add(Geom("arc", *self.pose, length, k=k))

    def spiral(self, k0: float, k1: float, length: float):
        assert length > 1e-6
        self._add(Geom("spiral", *self.pose, length, k0=k0, k1=k1))

    def ppoly(self, u, v):
        self._add(Geom("paramPoly3", *self.pose, ppoly_length(u, v), u=u, v=v))

    def corner(self, theta: float, r: float, ls: float):
        """Clothoid (0 -> 1/r), arc, clothoid (1/r -> 0) turning by theta (left positive)."""
        k = math.copysign(1.0 / r, theta)
        arc_len = r * abs(theta) - ls
        assert arc_len >= 0.0, "clothoids longer than the turn"
        self.spiral(0.0, k, ls)
        if arc_len > 1e-6:
            self.arc(k, arc_len)
        self.spiral(k, 0.0, ls)


def corner_tangent(theta: float, r: float, ls: float) -> float:
    """Distance from a symmetric corner's ends to the intersection of its tangents."""
    p = RefLine(0.0, 0.0, 0.0)
    p.corner(theta, r, ls)
    xe, ye, he = p.pose
    assert abs(wrap(he - theta)) < 1e-12
    t2 = ye / math.sin(theta)
    t1 = xe - t2 * math.cos(theta)
    assert abs(t1 - t2) < 1e-9, (t1, t2)
    return t1


def rounded_polyline(points, corners) -> RefLine:
    """Straight lines through points[0], the vertices points[1:-1], points[-1]; each vertex rounded
    by the (r, ls) corner in `corners`. The result starts at points[0] heading to points[1] and is
    checked to end at points[-1] heading away from points[-2]."""
    assert len(corners) == len(points) - 2
    heads = [math.atan2(b[1] - a[1], b[0] - a[0]) for a, b in zip(points, points[1:])]
    dists = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(points, points[1:])]
    tangents = []
    for i, (r, ls) in enumerate(corners):
        tangents.append(corner_tangent(wrap(heads[i + 1] - heads[i]), r, ls))
    path = RefLine(points[0][0], points[0][1], heads[0])
    for i, d in enumerate(dists):
        before = tangents[i - 1] if i > 0 else 0.0
        after = tangents[i] if i < len(tangents) else 0.0
        straight = d - before - after
        assert straight > -1e-9, f"polyline leg {i} too short by {-straight} m"
        if straight > 1e-6:
            path.line(straight)
        if i < len(corners):
            path.corner(wrap(heads[i + 1] - heads[i]), *corners[i])
    xe, ye, he = path.pose
    assert math.hypot(xe - points[-1][0], ye - points[-1][1]) < 1e-9, (path.pose, points[-1])
    assert abs(wrap(he - heads[-1])) < 1e-12
    return path


# ----------------------------------------------------------------------------------------------
# Roads, lanes, junctions
# ----------------------------------------------------------------------------------------------


class Lane:
    def __init__(self, lid: int, kind: str = "driving", width=(LANE_W, 0.0, 0.0, 0.0), mark=None,
                 pred: int | None = None, succ: int | None = None):
        self.id, self.kind, self.width, self.mark, self.pred, self.succ = lid, kind, width, mark, pred, succ


class Section:
    def __init__(self, s: float, lanes: list[Lane], centre_mark: str | None):
        self.s, self.lanes, self.centre_mark = s, lanes, centre_mark


class Road:
    def __init__(self, rid: int, name: str, path: RefLine, sections: list[Section], speed: int,
                 junction: int = -1, lane_offset=None):
        self.id, self.name, self.path, self.sections, self.speed = rid, name, path, sections, speed
        self.junction = junction
        self.lane_offset = lane_offset  # (a, b, c, d) at s = 0, or None
        self.pred = None  # ("road"|"junction", id, contactPoint|None)
        self.succ = None

    @property
    def length(self) -> float:
        return self.path.s


def two_by_two(s: float = 0.0, pred: bool = True, succ: bool = True, marks=True) -> Section:
    """2 lanes each way; lane links to the same ids where asked."""
    lanes = []
    for lid in (2, 1, -1, -2):
        mark = ("solid" if abs(lid) == 2 else "broken") if marks else None
        lanes.append(Lane(lid, mark=mark, pred=lid if pred else None, succ=lid if succ else None))
    return Section(s, lanes, "solid solid" if marks else None)


def connector(rid: int, junction: int, path: RefLine, lane_ids, preds, succs, speed: int, kind="driving",
              lane_offset=None, name: str = "") -> Road:
    """A connecting road: right lanes only, no marks; lane links to the incoming and outgoing roads."""
    lanes = [Lane(l, kind=kind, pred=p, succ=q) for l, p, q in zip(lane_ids, preds, succs)]
    return Road(rid, name or f"junction {junction} connecting road {rid}", path, [Section(0.0, lanes, None)],
                speed, junction=junction, lane_offset=lane_offset)


def cubic_step(a: float, b: float, length: float):
    """Polynomial going from a to b over `length` with zero slope at both ends."""
    d = b - a
    return (a, 0.0, 3.0 * d / length**2, -2.0 * d / length**3)


def build():
    roads: dict[int, Road] = {}
    junctions: dict[int, list] = {100: [], 200: [], 300: []}
    names = {100: "intersection", 200: "ramp diverge", 300: "ramp merge"}

    def add(road: Road):
        assert road.id not in roads
        roads[road.id] = road
        return road

    main_corner_a = (LOBE_A_R, LOBE_A_LS)
    main_corner_b = (LOBE_B_R, LOBE_B_LS)
    top_b = J2_TOP - JL  # y of the diverge junction's downstream edge
    ramp_x = -(2 * LANE_W + GAP)  # x of the ramp's reference line (its lane's left edge) going south
    ramp_y = -LOBE_B_H + 2 * LANE_W + GAP  # y of the ramp's reference line going west

    # ---- the loop
    r1 = add(Road(1, "north-east lobe", rounded_polyline(
        [(A, 0.0), (LOBE_A, 0.0), (LOBE_A, LOBE_A), (0.0, LOBE_A), (0.0, A)], [main_corner_a] * 3),
        [two_by_two(pred=False, succ=False)], SPEED_MAIN))
    r2 = add(Road(2, "south arm", rounded_polyline([(0.0, -A), (0.0, J2_TOP)], []),
                  [two_by_two(pred=False, succ=False)], SPEED_MAIN))
    r3 = add(Road(3, "south-east corner", rounded_polyline(
        [(0.0, top_b), (0.0, -LOBE_B_H), (X3, -LOBE_B_H)], [main_corner_b]),
        [two_by_two(pred=False, succ=False)], SPEED_MAIN))
    # Road 5: 3 lanes westwards for L_3LANE, then lane -3 tapers to zero width (cubic).
    p5 = RefLine(X3 - JL, -LOBE_B_H, math.pi)
    p5.line(L_3LANE + L_TAPER)
    sec_a = Section(0.0, [
        Lane(2, mark="solid", succ=2), Lane(1, mark="broken", succ=1),
        Lane(-1, mark="broken", succ=-1), Lane(-2, mark="broken", succ=-2), Lane(-3, mark="solid", succ=-3),
    ], "solid solid")
    sec_b = Section(L_3LANE, [
        Lane(2, mark="solid", pred=2, succ=2), Lane(1, mark="broken", pred=1, succ=1),
        Lane(-1, mark="broken", pred=-1, succ=-1), Lane(-2, mark="broken", pred=-2, succ=-2),
        Lane(-3, mark="solid", width=cubic_step(LANE_W, 0.0, L_TAPER), pred=-3),
    ], "solid solid")
    r5 = add(Road(5, "three-lane straight", p5, [sec_a, sec_b], SPEED_MAIN))
    r6 = add(Road(6, "west lobe", rounded_polyline(
        [(X3 - JL - L_3LANE - L_TAPER, -LOBE_B_H), (-LOBE_B_W, -LOBE_B_H), (-LOBE_B_W, 0.0), (-A, 0.0)],
        [main_corner_b] * 2), [two_by_two(succ=False)], SPEED_MAIN))
    # The on-ramp: one lane, its reference line on the lane's left edge.
    ramp_q = (ramp_x, ramp_y)
    r4 = add(Road(4, "on-ramp", rounded_polyline(
        [(ramp_x, top_b), (ramp_q[0], ramp_q[1] + RAMP_D), (ramp_q[0] - RAMP_D, ramp_q[1]), (X3, ramp_y)],
        [(RAMP_R, RAMP_LS)] * 2), [Section(0.0, [Lane(-1, kind="onRamp", mark="solid")], "solid")], SPEED_RAMP))

    r1.pred, r1.succ = ("junction", 100, None), ("junction", 100, None)
    r2.pred, r2.succ = ("junction", 100, None), ("junction", 200, None)
    r3.pred, r3.succ = ("junction", 200, None), ("junction", 300, None)
    r4.pred, r4.succ = ("junction", 200, None), ("junction", 300, None)
    r5.pred, r5.succ = ("junction", 300, None), ("road", 6, "start")
    r6.pred, r6.succ = ("road", 5, "end"), ("junction", 100, None)

    def link(conn: Road, junction: int, incoming: Road, in_contact: str, outgoing: Road, out_contact: str,
             lane_links):
        conn.pred = ("road", incoming.id, in_contact)
        conn.succ = ("road", outgoing.id, out_contact)
        junctions[junction].append((incoming.id, conn.id, lane_links))
        add(conn)

    # ---- junction 100: the intersection. Arms: (road, contact, reference point, heading into the
    # junction along the inbound lanes, inbound lane ids inner/outer, outbound lane ids inner/outer).
    arms = {
        "E": (r1, "start", (A, 0.0), math.pi, (1, 2), (-1, -2)),
        "N": (r1, "end", (0.0, A), -math.pi / 2, (-1, -2), (1, 2)),
        "W": (r6, "end", (-A, 0.0), 0.0, (-1, -2), (1, 2)),
        "S": (r2, "start", (0.0, -A), math.pi / 2, (1, 2), (-1, -2)),
    }
    rid = 101
    for src in ("E", "N", "W", "S"):
        road_in, c_in, p_in, h_in, in_ids, _ = arms[src]
        for turn, dh in (("straight", 0.0), ("left", math.pi / 2), ("right", -math.pi / 2)):
            h_out = wrap(h_in + dh)
            dst = next(k for k, a in arms.items() if abs(wrap(a[3] + math.pi - h_out)) < 1e-9)
            road_out, c_out, p_out, _, _, out_ids = arms[dst]
            if turn == "straight":
                path = rounded_polyline([p_in, p_out], [])
                conn = connector(rid, 100, path, (-1, -2), in_ids, out_ids, SPEED_CROSS)
                lane_links = [(in_ids[0], -1), (in_ids[1], -2)]
            else:
                vertex = (0.0, 0.0)
                path = rounded_polyline([p_in, vertex, p_out], [(TURN_R, TURN_LS)])
                if turn == "left":  # inner lane to inner lane
                    conn = connector(rid, 100, path, (-1,), (in_ids[0],), (out_ids[0],), SPEED_TURN)
                    lane_links = [(in_ids[0], -1)]
                else:  # outer lane to outer lane, the lane 3.5 m right of the reference line
                    conn = connector(rid, 100, path, (-1,), (in_ids[1],), (out_ids[1],), SPEED_TURN,
                                     lane_offset=(-LANE_W, 0.0, 0.0, 0.0))
                    lane_links = [(in_ids[1], -1)]
            conn.name = f"intersection {src}->{dst} {turn}"
            link(conn, 100, road_in, c_in, road_out, c_out, lane_links)
            rid += 1

    # ---- junction 200: diverge. Through lanes both ways and the exit from lane -2 to the ramp.
    p = RefLine(0.0, J2_TOP, -math.pi / 2)
    p.line(JL)
    link(connector(201, 200, p, (-1, -2), (-1, -2), (-1, -2), SPEED_MAIN, name="diverge through southbound"),
         200, r2, "end", r3, "start", [(-1, -1), (-2, -2)])
    p = RefLine(0.0, top_b, math.pi / 2)
    p.line(JL)
    link(connector(202, 200, p, (-1, -2), (1, 2), (1, 2), SPEED_MAIN, name="diverge through northbound"),
         200, r3, "start", r2, "end", [(1, -1), (2, -2)])
    p = RefLine(0.0, J2_TOP, -math.pi / 2)
    shift = ramp_x  # heading south the ramp lies to the right: v = ramp_x (negative)
    p.ppoly((0.0, JL, 0.0, 0.0), (0.0, 0.0, 3.0 * shift, -2.0 * shift))
    exit_road = connector(203, 200, p, (-1,), (-2,), (-1,), SPEED_RAMP, kind="offRamp",
                          lane_offset=cubic_step(-LANE_W, 0.0, p.s))
    exit_road.name = "ramp exit"
    link(exit_road, 200, r2, "end", r4, "start", [(-2, -1)])

    # ---- junction 300: merge. Through lanes both ways; the ramp lane becomes road 5's lane -3.
    p = RefLine(X3, -LOBE_B_H, math.pi)
    p.line(JL)
    link(connector(301, 300, p, (-1, -2), (-1, -2), (-1, -2), SPEED_MAIN, name="merge through westbound"),
         300, r3, "end", r5, "start", [(-1, -1), (-2, -2)])
    p = RefLine(X3 - JL, -LOBE_B_H, 0.0)
    p.line(JL)
    link(connector(302, 300, p, (-1, -2), (1, 2), (1, 2), SPEED_MAIN, name="merge through eastbound"),
         300, r5, "start", r3, "end", [(1, -1), (2, -2)])
    p = RefLine(X3, ramp_y, math.pi)
    shift = ramp_y - (-LOBE_B_H)  # heading west, the main reference line lies to the left
    p.ppoly((0.0, JL, 0.0, 0.0), (0.0, 0.0, 3.0 * shift, -2.0 * shift))
    merge_road = connector(303, 300, p, (-1,), (-1,), (-3,), SPEED_RAMP, kind="onRamp",
                           lane_offset=cubic_step(0.0, -2 * LANE_W, p.s))
    merge_road.name = "ramp merge"
    link(merge_road, 300, r4, "end", r5, "start", [(-1, -1)])

    return roads, junctions, names


# ----------------------------------------------------------------------------------------------
# XML
# ----------------------------------------------------------------------------------------------


def bounds(roads) -> tuple[float, float, float, float]:
    xs, ys = [], []
    for r in roads.values():
        for g in r.path.geoms:
            n = max(2, math.ceil(g.length / 5.0))
            for i in range(n + 1):
                x, y, _ = g.pose(g.length * i / n)
                xs.append(x)
                ys.append(y)
    margin = 3 * LANE_W
    return (math.ceil(max(ys) + margin), math.floor(min(ys) - margin),
            math.ceil(max(xs) + margin), math.floor(min(xs) - margin))


def to_xml(roads, junctions, names) -> str:
    north, south, east, west = bounds(roads)
    out = ['<?xml version="1.0" encoding="UTF-8"?>']
    out.append("<!-- Generated by config/maps/proving_ground.py; edit that script, not this file. -->")
    out.append("<OpenDRIVE>")
    out.append(
        f'  <header revMajor="1" revMinor="7" name="Video2Track proving ground" version="1.0" '
        f'date="{MAP_DATE}" north="{north}" south="{south}" east="{east}" west="{west}" vendor="Video2Track">'
    )
    out.append(f"    <geoReference><![CDATA[{GEO_REFERENCE}]]></geoReference>")
    out.append("  </header>")
    for r in sorted(roads.values(), key=lambda r: r.id):
        out.append(
            f'  <road name="{r.name}" length="{fmt_pos(r.length)}" id="{r.id}" junction="{r.junction}" rule="RHT">'
        )
        out.append("    <link>")
        for tag, ln in (("predecessor", r.pred), ("successor", r.succ)):
            if ln is None:
                continue
            kind, lid, contact = ln
            cp = f' contactPoint="{contact}"' if contact else ""
            out.append(f'      <{tag} elementType="{kind}" elementId="{lid}"{cp}/>')
        out.append("    </link>")
        rtype = "town" if r.junction != -1 else "rural"
        out.append(f'    <type s="0" type="{rtype}">')
        out.append(f'      <speed max="{r.speed}" unit="km/h"/>')
        out.append("    </type>")
        out.append("    <planView>")
        for g in r.path.geoms:
            out.append(
                f'      <geometry s="{fmt_pos(g.s)}" x="{fmt_pos(g.x)}" y="{fmt_pos(g.y)}" '
                f'hdg="{fmt_num(wrap(g.hdg))}" length="{fmt_pos(g.length)}">'
            )
            if g.kind == "line":
                out.append("        <line/>")
            elif g.kind == "arc":
                out.append(f'        <arc curvature="{fmt_num(g.p["k"])}"/>')
            elif g.kind == "spiral":
                out.append(f'        <spiral curvStart="{fmt_num(g.p["k0"])}" curvEnd="{fmt_num(g.p["k1"])}"/>')
            else:
                u, v = g.p["u"], g.p["v"]
                out.append(
                    f'        <paramPoly3 aU="{fmt_num(u[0])}" bU="{fmt_num(u[1])}" cU="{fmt_num(u[2])}" '
                    f'dU="{fmt_num(u[3])}" aV="{fmt_num(v[0])}" bV="{fmt_num(v[1])}" cV="{fmt_num(v[2])}" '
                    f'dV="{fmt_num(v[3])}" pRange="normalized"/>'
                )
            out.append("      </geometry>")
        out.append("    </planView>")
        out.append("    <elevationProfile>")
        out.append('      <elevation s="0" a="0" b="0" c="0" d="0"/>')
        out.append("    </elevationProfile>")
        out.append("    <lateralProfile/>")
        out.append("    <lanes>")
        if r.lane_offset is not None:
            a, b, c, d = r.lane_offset
            out.append(f'      <laneOffset s="0" a="{fmt_num(a)}" b="{fmt_num(b)}" c="{fmt_num(c)}" d="{fmt_num(d)}"/>')
        for sec in r.sections:
            out.append(f'      <laneSection s="{fmt_pos(sec.s)}">')
            left = sorted((l for l in sec.lanes if l.id > 0), key=lambda l: -l.id)
            right = sorted((l for l in sec.lanes if l.id < 0), key=lambda l: -l.id)
            if left:
                out.append("        <left>")
                for l in left:
                    out.extend(lane_xml(l))
                out.append("        </left>")
            out.append("        <center>")
            if sec.centre_mark:
                out.append('          <lane id="0" type="none" level="false">')
                out.append(mark_xml(sec.centre_mark))
                out.append("          </lane>")
            else:
                out.append('          <lane id="0" type="none" level="false"/>')
            out.append("        </center>")
            if right:
                out.append("        <right>")
                for l in right:
                    out.extend(lane_xml(l))
                out.append("        </right>")
            out.append("      </laneSection>")
        out.append("    </lanes>")
        out.append("  </road>")
    for jid in sorted(junctions):
        out.append(f'  <junction name="{names[jid]}" id="{jid}" type="default">')
        for cid, (incoming, conn, lane_links) in enumerate(junctions[jid]):
            out.append(
                f'    <connection id="{cid}" incomingRoad="{incoming}" connectingRoad="{conn}" contactPoint="start">'
            )
            for f, t in lane_links:
                out.append(f'      <laneLink from="{f}" to="{t}"/>')
            out.append("    </connection>")
        out.append("  </junction>")
    out.append("</OpenDRIVE>")
    return "\n".join(out) + "\n"


def mark_xml(kind: str) -> str:
    return (
        f'            <roadMark sOffset="0" type="{kind}" weight="standard" color="white" width="0.15" '
        f'laneChange="{"both" if kind == "broken" else "none"}" height="0.02"/>'
    )


def lane_xml(l: Lane) -> list[str]:
    out = [f'          <lane id="{l.id}" type="{l.kind}" level="false">']
    if l.pred is not None or l.succ is not None:
        out.append("            <link>")
        if l.pred is not None:
            out.append(f'              <predecessor id="{l.pred}"/>')
        if l.succ is not None:
            out.append(f'              <successor id="{l.succ}"/>')
        out.append("            </link>")
    a, b, c, d = l.width
    out.append(f'            <width sOffset="0" a="{fmt_num(a)}" b="{fmt_num(b)}" c="{fmt_num(c)}" d="{fmt_num(d)}"/>')
    if l.mark:
        out.append(mark_xml(l.mark))
    out.append("          </lane>")
    return out


# ----------------------------------------------------------------------------------------------
# Verification, on the file's own text
# ----------------------------------------------------------------------------------------------


class Check:
    """The map as read back from the XML, with the evaluations the checks need."""

    def __init__(self, text: str):
        root = ET.fromstring(text)
        assert root.tag == "OpenDRIVE"
        h = root.find("header")
        assert h is not None and h.get("revMajor") == "1" and h.get("revMinor") in ("6", "7")
        assert h.find("geoReference") is not None and "+proj=" in (h.find("geoReference").text or "")
        self.roads = {}
        for r in root.findall("road"):
            rid = int(r.get("id"))
            assert rid not in self.roads, f"duplicate road {rid}"
            geoms = []
            for g in r.find("planView").findall("geometry"):
                at = {k: float(v) for k, v in g.attrib.items()}
                child = list(g)[0]
                c = {k: float(v) for k, v in child.attrib.items() if k != "pRange"}
                if child.tag == "line":
                    geo = Geom("line", at["x"], at["y"], at["hdg"], at["length"])
                elif child.tag == "arc":
                    geo = Geom("arc", at["x"], at["y"], at["hdg"], at["length"], k=c["curvature"])
                elif child.tag == "spiral":
                    geo = Geom("spiral", at["x"], at["y"], at["hdg"], at["length"], k0=c["curvStart"],
                               k1=c["curvEnd"])
                elif child.tag == "paramPoly3":
                    assert child.get("pRange") == "normalized"
                    geo = Geom("paramPoly3", at["x"], at["y"], at["hdg"], at["length"],
                               u=(c["aU"], c["bU"], c["cU"], c["dU"]), v=(c["aV"], c["bV"], c["cV"], c["dV"]))
                else:
                    raise AssertionError(f"road {rid}: unexpected geometry {child.tag}")
                geo.s = at["s"]
                geoms.append(geo)
            lanes = r.find("lanes")
            offsets = [tuple(float(o.get(k)) for k in ("s", "a", "b", "c", "d")) for o in lanes.findall("laneOffset")]
            sections = []
            for sec in lanes.findall("laneSection"):
                ls = {}
                for side in ("left", "right"):
                    el = sec.find(side)
                    if el is None:
                        continue
                    for lane in el.findall("lane"):
                        lid = int(lane.get("id"))
                        ws = lane.findall("width")
                        assert len(ws) == 1, f"road {rid} lane {lid}: one width record expected"
                        w = tuple(float(ws[0].get(k)) for k in ("a", "b", "c", "d"))
                        assert float(ws[0].get("sOffset")) == 0.0
                        ln = lane.find("link")
                        pred = succ = None
                        if ln is not None:
                            if ln.find("predecessor") is not None:
                                pred = int(ln.find("predecessor").get("id"))
                            if ln.find("successor") is not None:
                                succ = int(ln.find("successor").get("id"))
                        ls[lid] = {"type": lane.get("type"), "w": w, "pred": pred, "succ": succ}
                sections.append((float(sec.get("s")), ls))
            link = {}
            for tag in ("predecessor", "successor"):
                el = r.find("link").find(tag)
                if el is not None:
                    link[tag] = (el.get("elementType"), int(el.get("elementId")), el.get("contactPoint"))
            self.roads[rid] = {
                "length": float(r.get("length")), "junction": int(r.get("junction")), "geoms": geoms,
                "offsets": offsets, "sections": sections, "link": link,
            }
        self.junctions = {}
        for j in root.findall("junction"):
            conns = []
            for c in j.findall("connection"):
                conns.append((int(c.get("incomingRoad")), int(c.get("connectingRoad")), c.get("contactPoint"),
                              [(int(l.get("from")), int(l.get("to"))) for l in c.findall("laneLink")]))
            self.junctions[int(j.get("id"))] = conns

    # -- evaluation
    def geom_at(self, rid, s):
        geoms = self.roads[rid]["geoms"]
        g = geoms[0]
        for cand in geoms:
            if cand.s <= s + 1e-12:
                g = cand
        return g, s - g.s

    def pose(self, rid, s):
        g, ds = self.geom_at(rid, s)
        return g.pose(min(ds, g.length))

    def lane_offset(self, rid, s):
        val = 0.0
        for so, a, b, c, d in self.roads[rid]["offsets"]:
            if so <= s + 1e-12:
                ds = s - so
                val = a + ds * (b + ds * (c + ds * d))
        return val

    def section_index(self, rid, s, at_end: bool):
        secs = self.roads[rid]["sections"]
        if at_end:
            idx = [i for i, (so, _) in enumerate(secs) if so < s - 1e-9]
            return idx[-1]
        idx = [i for i, (so, _) in enumerate(secs) if so <= s + 1e-9]
        return idx[-1]

    def lane_edges(self, rid, sec_idx, lid, s):
        """(inner edge, centre, outer edge) points of a lane at road s."""
        so, lanes = self.roads[rid]["sections"][sec_idx]
        ds = s - so
        sign = 1 if lid > 0 else -1
        t = self.lane_offset(rid, s)
        inner = outer = None
        for k in range(1, abs(lid) + 1):
            a, b, c, d = lanes[sign * k]["w"]
            w = a + ds * (b + ds * (c + ds * d))
            inner, t = t, t + sign * w
            outer = t
        x, y, h = self.pose(rid, s)
        nx, ny = -math.sin(h), math.cos(h)
        return tuple((x + tt * nx, y + tt * ny) for tt in (inner, 0.5 * (inner + outer), outer))

    def width(self, rid, sec_idx, lid, s):
        so, lanes = self.roads[rid]["sections"][sec_idx]
        a, b, c, d = lanes[lid]["w"]
        ds = s - so
        return a + ds * (b + ds * (c + ds * d))


def dist(p, q):
    return math.hypot(p[0] - q[0], p[1] - q[1])


def verify(text: str) -> dict:
    m = Check(text)
    stats = {"links": 0, "worst_lane_gap": 0.0, "worst_road_gap": 0.0}

    # 1. planView: s consecutive, sums to the length, geometries end to end, curvature continuous.
    for rid, r in m.roads.items():
        geoms = r["geoms"]
        assert geoms[0].s == 0.0, f"road {rid}: first geometry at s {geoms[0].s}"
        for g0, g1 in zip(geoms, geoms[1:]):
            assert abs(g0.s + g0.length - g1.s) < 1e-9, f"road {rid}: s gap at {g1.s}"
            x, y, h = g0.end()
            assert math.hypot(x - g1.x, y - g1.y) < 1e-9, f"road {rid}: geometry gap at s {g1.s}"
            assert abs(wrap(h - g1.hdg)) < 1e-12, f"road {rid}: heading jump at s {g1.s}"
            assert abs(g0.curvature(g0.length) - g1.curvature(0.0)) < 1e-9, f"road {rid}: curvature jump at s {g1.s}"
        assert abs(geoms[-1].s + geoms[-1].length - r["length"]) < 1e-9, f"road {rid}: length"
        assert r["sections"][0][0] == 0.0 and all(
            a[0] < b[0] for a, b in zip(r["sections"], r["sections"][1:])), f"road {rid}: sections"

    def end_pose(rid, contact):
        return m.pose(rid, 0.0 if contact == "start" else m.roads[rid]["length"])

    def contact_s(rid, contact):
        return 0.0 if contact == "start" else m.roads[rid]["length"]

    def contact_section(rid, contact):
        return 0 if contact == "start" else len(m.roads[rid]["sections"]) - 1

    def compare_lanes(what, a, b):
        """a, b: (road, contact, lane id) pairs that must share both edges."""
        ea = m.lane_edges(a[0], contact_section(a[0], a[1]), a[2], contact_s(a[0], a[1]))
        eb = m.lane_edges(b[0], contact_section(b[0], b[1]), b[2], contact_s(b[0], b[1]))
        gap = max(dist(p, q) for p, q in zip(ea, eb))
        assert gap < TOL_POS, f"{what}: lane edges {gap} m apart"
        stats["links"] += 1
        stats["worst_lane_gap"] = max(stats["worst_lane_gap"], gap)

    # 2. Road links: reference lines end to end; lane links both ways on every lane with a width.
    for rid, r in m.roads.items():
        for tag, contact in (("predecessor", "start"), ("successor", "end")):
            ln = r["link"].get(tag)
            if ln is None or ln[0] != "road":
                continue
            other, ocontact = ln[1], ln[2]
            x0, y0, h0 = end_pose(rid, contact)
            x1, y1, h1 = end_pose(other, ocontact)
            gap = math.hypot(x1 - x0, y1 - y0)
            assert gap < TOL_POS, f"road {rid} {tag} {other}: {gap} m"
            stats["worst_road_gap"] = max(stats["worst_road_gap"], gap)
            flip = 0.0 if contact != ocontact else math.pi
            assert abs(wrap(h1 - h0 - flip)) < TOL_HDG, f"road {rid} {tag} {other}: heading"
            # The other road links back (to this road, or to this road's junction for connectors).
            back = m.roads[other]["link"]["predecessor" if ocontact == "start" else "successor"]
            if r["junction"] == -1:
                assert back[:2] == ("road", rid) and back[2] == contact, f"road {rid}: {other} does not link back"
            else:
                assert back[:2] == ("junction", r["junction"]), f"road {rid}: {other} not on junction {r['junction']}"
            sec = contact_section(rid, contact)
            lanes = m.roads[rid]["sections"][sec][1]
            olanes = m.roads[other]["sections"][contact_section(other, ocontact)][1]
            for lid, lane in lanes.items():
                target = lane["pred" if contact == "start" else "succ"]
                w = m.width(rid, sec, lid, contact_s(rid, contact))
                if w < 1e-9:
                    assert target is None, f"road {rid} lane {lid}: zero width with a link"
                    continue
                assert target is not None, f"road {rid} lane {lid}: no {tag} lane"
                assert target in olanes, f"road {rid} lane {lid}: {tag} lane {target} missing on road {other}"
                if r["junction"] == -1 and m.roads[other]["junction"] == -1:
                    back_id = olanes[target]["pred" if ocontact == "start" else "succ"]
                    assert back_id == lid, f"road {rid} lane {lid}: {other} lane {target} links to {back_id}"
                assert lane["type"] == olanes[target]["type"] or r["junction"] != -1 or m.roads[other]["junction"] != -1
                compare_lanes(f"road {rid} lane {lid} -> road {other} lane {target}",
                              (rid, contact, lid), (other, ocontact, target))
            if r["junction"] == -1 and m.roads[other]["junction"] == -1:
                for olid in olanes:
                    w = m.width(other, contact_section(other, ocontact), olid, contact_s(other, ocontact))
                    if w > 1e-9:
                        assert any(l["pred" if contact == "start" else "succ"] == olid for l in lanes.values()), \
                            f"road {other} lane {olid}: nothing links to it from road {rid}"

    # 3. Lane links between the sections of a road.
    for rid, r in m.roads.items():
        for i in range(1, len(r["sections"])):
            s = r["sections"][i][0]
            prev, cur = r["sections"][i - 1][1], r["sections"][i][1]
            for lid, lane in prev.items():
                w = m.width(rid, i - 1, lid, s)
                if w < 1e-9:
                    assert lane["succ"] is None
                    continue
                t = lane["succ"]
                assert t is not None and cur[t]["pred"] == lid, f"road {rid} lane {lid} at s {s}"
                ea, eb = m.lane_edges(rid, i - 1, lid, s), m.lane_edges(rid, i, t, s)
                gap = max(dist(p, q) for p, q in zip(ea, eb))
                assert gap < TOL_POS, f"road {rid} lane {lid} at s {s}: {gap}"
                stats["links"] += 1
            for lid, lane in cur.items():
                if m.width(rid, i, lid, s) > 1e-9:
                    assert lane["pred"] is not None and prev[lane["pred"]]["succ"] == lid, f"road {rid} lane {lid}"

    # 4. Junctions: each connecting road appears once, starts at its incoming road; lane links agree.
    seen = set()
    for jid, conns in m.junctions.items():
        for incoming, conn, cp, lane_links in conns:
            assert cp == "start" and conn not in seen
            seen.add(conn)
            c = m.roads[conn]
            assert c["junction"] == jid
            kind, pid, pcontact = c["link"]["predecessor"]
            assert (kind, pid) == ("road", incoming)
            assert m.roads[incoming]["link"]["predecessor" if pcontact == "start" else "successor"][:2] == ("junction", jid)
            clanes = c["sections"][0][1]
            assert sorted(t for _, t in lane_links) == sorted(clanes), f"connection {conn}: every lane linked"
            for f, t in lane_links:
                assert clanes[t]["pred"] == f, f"connection {conn}: lane {t} predecessor"
                # Inbound lanes only: right lanes at an incoming road's end, left lanes at its start.
                assert (f < 0) == (pcontact == "end"), f"connection {conn}: lane {f} runs out of the junction"
                compare_lanes(f"junction {jid} road {incoming} lane {f} -> road {conn} lane {t}",
                              (incoming, pcontact, f), (conn, "start", t))
    assert seen == {rid for rid, r in m.roads.items() if r["junction"] != -1}

    # 5. Lane graph in the driving direction: strongly connected; only a taper ends.
    nodes, edges = [], {}
    for rid, r in m.roads.items():
        for i, (_, lanes) in enumerate(r["sections"]):
            for lid, lane in lanes.items():
                if lane["type"] in ("driving", "onRamp", "offRamp", "entry", "exit"):
                    nodes.append((rid, i, lid))
    node_set = set(nodes)
    for n in nodes:
        edges[n] = set()
    for rid, i, lid in nodes:
        r = m.roads[rid]
        secs = r["sections"]
        forward = lid < 0
        lane = secs[i][1][lid]
        nxt = lane["succ"] if forward else lane["pred"]
        j = i + 1 if forward else i - 1
        if 0 <= j < len(secs):
            if nxt is not None:
                edges[(rid, i, lid)].add((rid, j, nxt))
        else:
            contact = "end" if forward else "start"
            ln = r["link"].get("successor" if forward else "predecessor")
            if ln and ln[0] == "road" and nxt is not None:
                other, ocontact = ln[1], ln[2]
                target = (other, contact_section(other, ocontact), nxt)
                # Entered at its start, a lane must run forwards (right); at its end, backwards (left).
                assert (nxt < 0) == (ocontact == "start"), f"road {rid} lane {lid} enters {target} against its direction"
                edges[(rid, i, lid)].add(target)
            elif ln and ln[0] == "junction":
                for incoming, conn, _, lane_links in m.junctions[ln[1]]:
                    pc = m.roads[conn]["link"]["predecessor"]
                    if incoming == rid and pc[2] == contact:
                        for f, t in lane_links:
                            if f == lid:
                                edges[(rid, i, lid)].add((conn, 0, t))
        # Lane changes to a neighbour running the same way.
        for nb in (lid - 1, lid + 1):
            if nb != 0 and (nb < 0) == (lid < 0) and (rid, i, nb) in node_set:
                edges[(rid, i, lid)].add((rid, i, nb))
    for n in nodes:
        assert edges[n] <= node_set, f"{n}: edge to a missing lane"
        rid, i, lid = n
        has_next = any(e[0] != rid or e[1] != i for e in edges[n])
        if not has_next:
            so = m.roads[rid]["sections"][i][0]
            end_s = m.roads[rid]["sections"][i + 1][0] if i + 1 < len(m.roads[rid]["sections"]) else m.roads[rid]["length"]
            downstream = end_s if lid < 0 else so
            assert m.width(rid, i, lid, downstream) < 1e-9, f"{n}: dead end"
            assert edges[n], f"{n}: dropped lane with no neighbour to merge into"

    def reach(start, adj):
        seen_, todo = {start}, [start]
        while todo:
            for nb in adj[todo.pop()]:
                if nb not in seen_:
                    seen_.add(nb)
                    todo.append(nb)
        return seen_

    radj = {n: set() for n in nodes}
    for a, bs in edges.items():
        for b in bs:
            radj[b].add(a)
    assert reach(nodes[0], edges) == node_set, "lane graph: not every lane reachable"
    assert reach(nodes[0], radj) == node_set, "lane graph: not every lane leads back"
    stats["lanes"] = len(nodes)

    # 6. The on-ramp keeps clear of the carriageway: ramp lane edge to the main lanes' edge.
    def samples(rid, step=1.0):
        pts = []
        n = max(2, math.ceil(m.roads[rid]["length"] / step))
        for k in range(n + 1):
            s = m.roads[rid]["length"] * k / n
            pts.append(m.pose(rid, s))
        return pts

    main = [p for rid in (2, 3, 5, 6) for p in samples(rid, 2.0)]
    worst = math.inf
    for x, y, h in samples(4, 1.0):
        # The ramp lane's right edge is 3.5 m right of its reference line, which is its left edge.
        for px, py, _ in main:
            worst = min(worst, math.hypot(x - px, y - py))
    # main reference line -> its right edge 7 m (inner lanes), plus the gap
    assert worst > 2 * LANE_W + GAP - 1e-6, f"ramp only {worst} m from the main reference line"
    stats["ramp_clearance"] = worst - 2 * LANE_W
    return stats


def same_within(a: str, b: str, tol: float = 1e-8) -> bool:
    """Texts equal but for numbers that differ by less than tol (another libm's last digit)."""
    num = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
    if num.sub("#", a) != num.sub("#", b):
        return False
    return all(abs(float(x) - float(y)) <= tol for x, y in zip(num.findall(a), num.findall(b)))


def main(argv) -> int:
    roads, junctions, names = build()
    text = to_xml(roads, junctions, names)
    stats = verify(text)
    if "--check" in argv:
        old = OUTPUT.read_text() if OUTPUT.exists() else ""
        if old != text and not same_within(old, text):
            print(f"{OUTPUT} is out of date: run python3 {FilePath(__file__).name}", file=sys.stderr)
            return 1
    else:
        OUTPUT.write_text(text)
    # One lap of the figure eight along the main carriageway, straight through every junction.
    lap = sum(roads[r].length for r in (1, 104, 2, 201, 3, 301, 5, 6, 107))
    outside = sum(r.length for r in roads.values() if r.junction == -1)
    print(f"{OUTPUT.name}: {len(roads)} roads, {len(junctions)} junctions, {stats['lanes']} driving lanes, "
          f"{stats['links']} lane links checked (worst gap {stats['worst_lane_gap']:.1e} m), "
          f"ramp clearance {stats['ramp_clearance']:.2f} m; lap {lap:.1f} m, roads outside junctions {outside:.1f} m")
    print("| road | junction | name | length m | lanes left/right by section | geometry |")
    print("| ---: | ---: | --- | ---: | --- | --- |")
    for r in sorted(roads.values(), key=lambda r: r.id):
        kinds = ", ".join(sorted({g.kind for g in r.path.geoms}))
        lanes = ", ".join(f"{sum(1 for l in s.lanes if l.id > 0)}/{sum(1 for l in s.lanes if l.id < 0)}"
                          for s in r.sections)
        junction = "" if r.junction == -1 else str(r.junction)
        print(f"| {r.id} | {junction} | {r.name} | {r.length:.3f} | {lanes} | {kinds} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
