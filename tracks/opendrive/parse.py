"""Parse an OpenDRIVE file with xml.etree into `tracks.opendrive.model` (the subset the reader uses).

Every problem becomes one `OpenDriveError` line naming the file, the element and why. Elements outside the
subset (elevation, superelevation, lateral profiles, objects, signals, controllers, geo-reference) are
skipped without a word.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from tracks.opendrive.limits import check_road
from tracks.opendrive.model import (
    Connection,
    Geometry,
    Junction,
    LaneRecord,
    LaneSection,
    Link,
    OpenDrive,
    OpenDriveError,
    Poly3,
    Road,
    RoadMark,
)

GEOMETRY_PARAMS = {
    "line": (),
    "arc": ("curvature",),
    "spiral": ("curvStart", "curvEnd"),
    "poly3": ("a", "b", "c", "d"),
    "paramPoly3": ("aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV"),
}
SUPPORTED_REVISIONS = range(4, 9)  # 1.4 .. 1.8
EGO_LANE_CODE = "ld3:egoLane"  # header userData: the ego lane id on a route's first road


class _Where:
    """Names the element being read in error messages: `file: road 3 <geometry s=10>: why`."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, why: str) -> OpenDriveError:
        return OpenDriveError(f"{self.source}: {where}: {why}")

    def number(self, elem: ET.Element, name: str, where: str, default: float | None = None) -> float:
        text = elem.get(name)
        if text is None:
            if default is None:
                raise self.fail(where, f"attribute {name!r} is missing")
            return default
        try:
            value = float(text)
        except ValueError:
            raise self.fail(where, f"attribute {name}={text!r} is not a number") from None
        if not math.isfinite(value):
            raise self.fail(where, f"attribute {name}={text!r} is not finite")
        return value

    def poly(self, elem: ET.Element, s_name: str, where: str) -> Poly3:
        return Poly3(*(self.number(elem, k, where) for k in (s_name, "a", "b", "c", "d")))


def read_file(path: Path) -> OpenDrive:
    """The parsed file at `path` (OpenDriveError if missing, not XML, not OpenDRIVE 1.4-1.8 or unusable)."""
    where = _Where(str(path))
    if not path.is_file():
        raise where.fail("file", "not found" if not path.exists() else "not a regular file")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise where.fail("file", f"not XML ({exc})") from None
    except OSError as exc:
        raise where.fail("file", f"cannot be read ({exc.strerror})") from None
    return parse_root(_without_namespace(root), where)


def _without_namespace(root: ET.Element) -> ET.Element:
    """The tree with every tag's XML namespace (`{uri}tag`) dropped, as files with a default namespace have."""
    for elem in root.iter():
        if isinstance(elem.tag, str) and elem.tag.startswith("{"):
            elem.tag = elem.tag.partition("}")[2]
    return root


def parse_root(root: ET.Element, where: _Where) -> OpenDrive:
    if root.tag != "OpenDRIVE":
        raise where.fail(f"<{root.tag}>", "the root element is not <OpenDRIVE>")
    header = root.find("header")
    if header is None:
        raise where.fail("<OpenDRIVE>", "no <header>")
    major = int(where.number(header, "revMajor", "<header>"))
    minor = int(where.number(header, "revMinor", "<header>"))
    if major != 1 or minor not in SUPPORTED_REVISIONS:
        raise where.fail("<header>", f"OpenDRIVE {major}.{minor} is not supported (1.4 to 1.8 are)")
    od = OpenDrive(where.source, (major, minor), _ego_lane(header, where))
    for elem in root.findall("road"):
        road = _road(elem, where)
        if road.id in od.roads:
            raise where.fail(f"road {road.id}", "the id is used twice")
        check_road(road, where.source)
        od.roads[road.id] = road
    if not od.roads:
        raise where.fail("<OpenDRIVE>", "no <road>")
    for elem in root.findall("junction"):
        junction = _junction(elem, where)
        od.junctions[junction.id] = junction
    return od


def _ego_lane(header: ET.Element, where: _Where) -> int | None:
    for data in header.findall("userData"):
        if data.get("code") == EGO_LANE_CODE:
            return int(where.number(data, "value", f"<header> <userData code={EGO_LANE_CODE}>"))
    return None


def _road(elem: ET.Element, where: _Where) -> Road:
    road_id = elem.get("id")
    if road_id is None:
        raise where.fail("<road>", "attribute 'id' is missing")
    name = f"road {road_id}"
    length = where.number(elem, "length", name)
    rule = elem.get("rule", "RHT")
    if rule not in ("RHT", "LHT"):
        raise where.fail(name, f"rule={rule!r} is neither RHT nor LHT")
    plan = elem.find("planView")
    if plan is None:
        raise where.fail(name, "no <planView>")
    geometries = tuple(_geometry(g, where, name) for g in plan.findall("geometry"))
    if not geometries:
        raise where.fail(f"{name} <planView>", "no <geometry>")
    lanes = elem.find("lanes")
    if lanes is None:
        raise where.fail(name, "no <lanes>")
    offsets = tuple(sorted((where.poly(o, "s", f"{name} <laneOffset>") for o in lanes.findall("laneOffset")),
                           key=lambda o: o.s))
    sections = tuple(_section(sec, where, name) for sec in lanes.findall("laneSection"))
    if not sections:
        raise where.fail(f"{name} <lanes>", "no <laneSection>")
    link = elem.find("link")
    pred = succ = None
    if link is not None:
        pred = _link(link.find("predecessor"), where, name)
        succ = _link(link.find("successor"), where, name)
    return Road(road_id, length, elem.get("junction", "-1"), rule, geometries, offsets,
                tuple(sorted(sections, key=lambda sec: sec.s)), pred, succ)


def _geometry(elem: ET.Element, where: _Where, road: str) -> Geometry:
    s = where.number(elem, "s", f"{road} <geometry>")
    name = f"{road} <geometry s={s:g}>"
    values = [where.number(elem, k, name) for k in ("x", "y", "hdg", "length")]
    if values[3] <= 0.0:
        raise where.fail(name, f"length {values[3]:g} is not positive")
    shapes = [child for child in elem if child.tag in GEOMETRY_PARAMS]
    if len(shapes) != 1:
        others = [child.tag for child in elem]
        why = (f"unsupported geometry <{others[0]}> (supported: {', '.join(GEOMETRY_PARAMS)})" if others
               else "no geometry element inside")
        raise where.fail(name, why if not shapes else "more than one geometry element inside")
    shape = shapes[0]
    params = {k: where.number(shape, k, f"{name} <{shape.tag}>") for k in GEOMETRY_PARAMS[shape.tag]}
    if shape.tag == "paramPoly3":
        p_range = shape.get("pRange", "normalized")
        if p_range not in ("arcLength", "normalized"):
            raise where.fail(f"{name} <paramPoly3>", f"pRange={p_range!r} is neither arcLength nor normalized")
        params["normalized"] = float(p_range == "normalized")
    return Geometry(s, *values, kind=shape.tag, params=params)


def _section(elem: ET.Element, where: _Where, road: str) -> LaneSection:
    s = where.number(elem, "s", f"{road} <laneSection>")
    name = f"{road} <laneSection s={s:g}>"
    lanes = []
    for side in ("left", "center", "right"):
        group = elem.find(side)
        for lane in () if group is None else group.findall("lane"):
            lanes.append(_lane(lane, where, name))
    return LaneSection(s, tuple(lanes))


def _lane(elem: ET.Element, where: _Where, section: str) -> LaneRecord:
    lane_id = int(where.number(elem, "id", f"{section} <lane>"))
    name = f"{section} lane {lane_id}"
    widths = tuple(sorted((where.poly(w, "sOffset", f"{name} <width>") for w in elem.findall("width")),
                          key=lambda p: p.s))
    border_only = lane_id != 0 and not widths and elem.find("border") is not None
    if lane_id != 0 and not widths and not border_only:
        raise where.fail(name, "no <width>")
    marks = tuple(sorted((RoadMark(where.number(m, "sOffset", f"{name} <roadMark>", 0.0), m.get("type", "none"),
                                   m.get("color", "standard")) for m in elem.findall("roadMark")),
                         key=lambda m: m.s_offset))
    link = elem.find("link")
    ends = [None if link is None else link.find(tag) for tag in ("predecessor", "successor")]
    pred, succ = (None if end is None else int(where.number(end, "id", f"{name} <{end.tag}>")) for end in ends)
    return LaneRecord(lane_id, elem.get("type", "driving"), widths, marks, pred, succ, border_only)


def _link(elem: ET.Element | None, where: _Where, road: str) -> Link | None:
    if elem is None:
        return None
    kind, ident = elem.get("elementType"), elem.get("elementId")
    if kind not in ("road", "junction") or ident is None:
        raise where.fail(f"{road} <{elem.tag}>", "needs elementType road|junction and an elementId")
    return Link(kind, ident, elem.get("contactPoint"))


def _junction(elem: ET.Element, where: _Where) -> Junction:
    junction_id = elem.get("id")
    if junction_id is None:
        raise where.fail("<junction>", "attribute 'id' is missing")
    direct = elem.get("type") == "direct"
    target = "linkedRoad" if direct else "connectingRoad"
    connections = []
    for conn in elem.findall("connection"):
        name = f"junction {junction_id} <connection id={conn.get('id')}>"
        incoming, connecting = conn.get("incomingRoad"), conn.get(target)
        if incoming is None or connecting is None:
            missing = " and ".join(k for k, v in (("incomingRoad", incoming), (target, connecting)) if v is None)
            raise where.fail(name, f"attribute {missing} is missing")
        links = tuple((int(where.number(ll, "from", f"{name} <laneLink>")),
                       int(where.number(ll, "to", f"{name} <laneLink>"))) for ll in conn.findall("laneLink"))
        connections.append(Connection(incoming, connecting, conn.get("contactPoint", "start"), links))
    return Junction(junction_id, tuple(connections), direct)
