"""Write a `Track` as OpenDRIVE 1.7: the reference line on the ego lane's centre, the lanes along it right of a
centre lane on the leftmost such lane line (through `laneOffset`), oncoming lanes left of it, shoulders as
shoulder lanes, a curb edge as a curb lane (on the left only beyond oncoming lanes).

Every intersection zone becomes a junction with one connecting road (no cross street); the roads between are
joined through it lane by lane. The header's `<userData code="ld3:egoLane">` names the ego lane's id. Lines,
arcs and clothoids are written as line, arc and spiral records; lane widths and the lane offset of a track with
width profiles as piecewise-linear records.
"""

from __future__ import annotations

import datetime
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from tracks.geometry import Arc, Clothoid, Straight
from tracks.opendrive.marks import road_mark
from tracks.opendrive.parse import EGO_LANE_CODE
from tracks.road import Track

JUNCTION_IDS = 1000  # junction k has id JUNCTION_IDS + k, apart from the road ids 1..n


def _num(v: float) -> str:
    return repr(float(v))


def _pieces(track: Track) -> list[tuple[float, float, bool]]:
    """(s0, s1, inside a junction) for every road the track is cut into."""
    cuts, s = [], 0.0
    for a, b in track.intersections:
        if a > s:
            cuts.append((s, a, False))
        cuts.append((max(a, s), min(b, track.length), True))
        s = b
    if s < track.length:
        cuts.append((s, track.length, False))
    return [c for c in cuts if c[1] - c[0] > 1e-6]


def _plan_view(track: Track, s0: float, s1: float) -> ET.Element:
    plan = ET.Element("planView")
    ref = track.reference
    start = 0.0
    for seg in ref.segments:
        a, b = max(start, s0), min(start + seg.length, s1)
        if b - a > 1e-9:
            x, y, _ = ref.frame(a)
            geom = ET.SubElement(plan, "geometry", s=_num(a - s0), x=_num(x), y=_num(y), hdg=_num(ref.heading_at(a)),
                                 length=_num(b - a))
            if isinstance(seg, Straight):
                ET.SubElement(geom, "line")
            elif isinstance(seg, Arc):
                ET.SubElement(geom, "arc", curvature=_num(1.0 / seg.radius))
            else:
                assert isinstance(seg, Clothoid)
                dk = (seg.k1 - seg.k0) / seg.length
                ET.SubElement(geom, "spiral", curvStart=_num(seg.k0 + dk * (a - start)),
                              curvEnd=_num(seg.k0 + dk * (b - start)))
        start += seg.length
    return plan


def _linear_records(s: np.ndarray, v: np.ndarray, s0: float, s1: float) -> list[tuple[float, float, float]]:
    """(start, value, slope) records of the piecewise-linear v(s) over [s0, s1], starts relative to s0, knots
    where the slope does not change dropped."""
    knots = np.unique(np.concatenate([[s0, s1], s[(s > s0) & (s < s1)]]))
    vals = np.interp(knots, s, v)
    slopes = np.diff(vals) / np.diff(knots)
    out: list[tuple[float, float, float]] = []
    for a, va, k in zip(knots[:-1], vals[:-1], slopes, strict=True):
        if not out or abs(k - out[-1][2]) > 1e-9:
            out.append((float(a - s0), float(va), float(k)))
    return out


def _poly(parent: ET.Element, tag: str, s_name: str, start: float, a: float, b: float = 0.0) -> None:
    ET.SubElement(parent, tag, **{s_name: _num(start), "a": _num(a), "b": _num(b), "c": "0.0", "d": "0.0"})


def _profile(track: Track, lane: int, s0: float, s1: float, what: int) -> list[tuple[float, float, float]]:
    """Records of lane `lane`'s centre offset (what=0) or width (what=1) over [s0, s1]."""
    ln = track.lanes[lane]
    if ln.profiles is None:
        return [(0.0, ln.offset if what == 0 else ln.width, 0.0)]
    p = ln.profiles[what]
    return _linear_records(p.s, p.v, s0, s1)


def _lanes(track: Track, s0: float, s1: float) -> ET.Element:
    lanes = ET.Element("lanes")
    n = len(track.lanes) - track.oncoming
    top = track.lanes[n - 1]
    if top.profiles is None:
        _poly(lanes, "laneOffset", "s", 0.0, track.boundaries[n].t)
    else:
        s = top.profiles[0].s
        left = top.profiles[0].v + 0.5 * top.profiles[1].v
        for start, a, b in _linear_records(s, left, s0, s1):
            _poly(lanes, "laneOffset", "s", start, a, b)
    section = ET.SubElement(lanes, "laneSection", s="0.0")
    middle = 0.5 * (s0 + s1)
    left_side = ET.SubElement(section, "left")
    for k in range(track.oncoming):
        _lane(left_side, k + 1, "driving", _profile(track, n + k, s0, s1, 1),
              track.boundaries[n + k + 1].kind_at(middle), link=True)
    _edge_lanes(left_side, track.oncoming + 1, 1, track.left.paved, track.oncoming > 0 and track.left.kind == "curb")
    if not len(left_side):
        section.remove(left_side)
    centre = ET.SubElement(ET.SubElement(section, "center"), "lane", id="0", type="none", level="false")
    _mark(centre, track.boundaries[n].kind_at(middle))
    right = ET.SubElement(section, "right")
    for k in range(n):
        i = n - 1 - k
        _lane(right, -(k + 1), "driving", _profile(track, i, s0, s1, 1), track.boundaries[i].kind_at(middle),
              link=True)
    _edge_lanes(right, n + 1, -1, track.right.paved, track.right.kind == "curb")
    return lanes


def _edge_lanes(side: ET.Element, first: int, sign: int, paved: float, curb: bool) -> None:
    """The shoulder (when `paved` > 0) and curb lanes of one side, ids from `first` outward (`sign` −1 right)."""
    lane_id = first
    if paved > 0.0:
        _lane(side, sign * lane_id, "shoulder", [(0.0, paved, 0.0)], "none")
        lane_id += 1
    if curb:
        _lane(side, sign * lane_id, "curb", [(0.0, 0.3, 0.0)], "none")


def _lane(side: ET.Element, lane_id: int, kind: str, widths: list[tuple[float, float, float]], mark: str,
          link: bool = False) -> None:
    lane = ET.SubElement(side, "lane", id=str(lane_id), type=kind, level="false")
    if link:
        ends = ET.SubElement(lane, "link")
        ET.SubElement(ends, "predecessor", id=str(lane_id))
        ET.SubElement(ends, "successor", id=str(lane_id))
    for start, a, b in widths:
        _poly(lane, "width", "sOffset", start, a, b)
    _mark(lane, mark)


def _mark(lane: ET.Element, kind: str) -> None:
    mark_type, color = road_mark(kind)
    ET.SubElement(lane, "roadMark", sOffset="0.0", type=mark_type, weight="standard", color=color, width="0.15",
                  laneChange="both" if kind == "dashed_white" else "none")


def track_to_xodr(track: Track) -> str:
    """The OpenDRIVE 1.7 text of `track`."""
    root = ET.Element("OpenDRIVE")
    header = ET.SubElement(root, "header", revMajor="1", revMinor="7", name=f"{track.name}@{track.seed}",
                           version="1.0", date=datetime.date(2000, 1, 1).isoformat(), vendor="ld3-testbed")
    ET.SubElement(header, "userData", code=EGO_LANE_CODE,
                  value=str(-(len(track.lanes) - track.oncoming - track.ego_lane)))
    pieces = _pieces(track)
    road_ids = [str(i + 1) for i in range(len(pieces))]
    junction_of = {}
    for i, (_, _, inside) in enumerate(pieces):
        if inside:
            junction_of[i] = str(JUNCTION_IDS + len(junction_of))
    for i, (s0, s1, inside) in enumerate(pieces):
        road = ET.SubElement(root, "road", name=f"{track.name} {s0:.0f}-{s1:.0f} m", length=_num(s1 - s0),
                             id=road_ids[i], junction=junction_of.get(i, "-1"), rule="RHT")
        link = ET.SubElement(road, "link")
        for tag, j, contact in (("predecessor", i - 1, "end"), ("successor", i + 1, "start")):
            if not 0 <= j < len(pieces):
                continue
            if j in junction_of and not inside:
                ET.SubElement(link, tag, elementType="junction", elementId=junction_of[j])
            else:
                ET.SubElement(link, tag, elementType="road", elementId=road_ids[j], contactPoint=contact)
        ET.SubElement(road, "type", s="0.0", type="town" if track.intersections else "rural")
        road.append(_plan_view(track, s0, s1))
        road.append(_lanes(track, s0, s1))
    for i, junction_id in junction_of.items():
        junction = ET.SubElement(root, "junction", id=junction_id, name=f"intersection {junction_id}")
        if i == 0:
            continue
        conn = ET.SubElement(junction, "connection", id="0", incomingRoad=road_ids[i - 1],
                             connectingRoad=road_ids[i], contactPoint="start")
        for k in range(len(track.lanes) - track.oncoming):
            ET.SubElement(conn, "laneLink", **{"from": str(-(k + 1)), "to": str(-(k + 1))})
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


def write_xodr(track: Track, path: Path) -> None:
    """Write `track` as OpenDRIVE 1.7 to `path`."""
    path.write_text(track_to_xodr(track), encoding="utf-8")

