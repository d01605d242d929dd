"""OpenDRIVE import: every geometry type, width changes and a junction route give map answers within 1 cm of
the file's analytic lane geometry; road marks become line kinds, connecting roads intersections."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import pytest

from tests.tracks.opendrive.map_check import map_errors
from tests.tracks.opendrive.xodr_text import constant, document, geometry, road, section
from tracks.opendrive.load import load_xodr

TWO_LANES = [section(0.0, [constant(3.5), constant(3.25)], [constant(3.5)])]
SHAPES = {
    "line": '<line/>',
    "arc-left": '<arc curvature="0.0125"/>',
    "arc-right": '<arc curvature="-0.00667"/>',
    "spiral": '<spiral curvStart="0.0" curvEnd="0.0166"/>',
    "poly3": '<poly3 a="0" b="0" c="0.002" d="-1.5e-5"/>',
    "paramPoly3-arcLength": ('<paramPoly3 aU="0" bU="1" cU="-0.001" dU="0" aV="0" bV="0" cV="0.003" dV="-2e-5" '
                             'pRange="arcLength"/>'),
    "paramPoly3-normalized": ('<paramPoly3 aU="0" bU="80" cU="-6.4" dU="0" aV="0" bV="0" cV="19.2" dV="-10.24" '
                              'pRange="normalized"/>'),
}


def _write(tmp_path, text: str, name: str = "road.xodr"):
    path = tmp_path / name
    path.write_text(text)
    return path, ET.fromstring(text)


@pytest.mark.parametrize("shape", SHAPES)
def test_each_geometry_type_matches_the_analytic_lanes_within_1_cm(shape, tmp_path):
    path, root = _write(tmp_path, document(road("7", 80.0, [geometry(0, 12.0, -4.0, 0.4, 80.0, SHAPES[shape])],
                                                TWO_LANES)))
    track = load_xodr(str(path))
    # lane −2 is track lane 0 and the ego lane (keep right), −1 track lane 1, the other side's lane 1 the oncoming
    # track lane 2
    assert len(track.lanes) == 3 and track.ego_lane == 0 and track.oncoming == 1 and track.lanes[2].oncoming
    assert [b.runs[0].kind for b in track.boundaries] == ["solid_white", "dashed_white", "solid_yellow", "solid_white"]
    worst = map_errors(track, root, [("7", 1)], step=4.0)
    assert worst["dev"] < 0.01 and worst["point"] < 0.01 and worst["width"] < 0.01, worst
    assert worst["heading"] < 1e-3, worst


def test_width_polynomials_sections_and_lane_offset_match_within_1_cm(tmp_path):
    widen = [(0.0, (3.25, 0.0, 3 * 0.5 / 60**2, -2 * 0.5 / 60**3))]  # 3.25 -> 3.75 m over 60 m, cubic
    sections = [section(0.0, [widen, constant(3.0)], [constant(3.5)]),
                section(60.0, [constant(3.75), [(0.0, (3.0, -0.5 / 70, 0.0, 0.0))]], [constant(3.5)])]
    held = 1e-4 * 95**2 - 7e-7 * 95**3  # the cubic lane offset's value at s = 95 m, held from there on
    offset = f'<laneOffset s="0" a="0" b="0" c="1e-4" d="-7e-7"/><laneOffset s="95" a="{held}" b="0" c="0" d="0"/>'
    text = document(road("3", 130.0, [geometry(0, 0.0, 0.0, 0.2, 130.0, '<arc curvature="0.005"/>')], sections,
                         lane_offset=offset))
    path, root = _write(tmp_path, text)
    track = load_xodr(str(path))
    assert track.lanes[0].profiles is not None
    worst = map_errors(track, root, [("3", 1)], step=3.0)
    assert worst["dev"] < 0.01 and worst["point"] < 0.01 and worst["width"] < 0.01, worst
    assert worst["heading"] < 0.02, worst  # a lane's heading is the ego line's; widths change by up to 1.25 %


def _junction_file() -> str:
    """Road 1 (line) → junction 100 (connecting road 10, a 90° left arc, right lanes only) → road 2 (line)."""
    r = 30.0
    link1 = '<successor elementType="junction" elementId="100"/>'
    link10 = ('<predecessor elementType="road" elementId="1" contactPoint="end"/>'
              '<successor elementType="road" elementId="2" contactPoint="start"/>')
    link2 = '<predecessor elementType="junction" elementId="100"/>'
    conn = ('<junction id="100"><connection id="0" incomingRoad="1" connectingRoad="10" contactPoint="start">'
            '<laneLink from="-1" to="-1"/><laneLink from="-2" to="-2"/></connection></junction>')
    one_way = [section(0.0, [constant(3.5), constant(3.25)])]
    return document(
        road("1", 60.0, [geometry(0, 0.0, 0.0, 0.0, 60.0, "<line/>")], TWO_LANES, link=link1),
        road("10", r * math.pi / 2, [geometry(0, 60.0, 0.0, 0.0, r * math.pi / 2, f'<arc curvature="{1 / r}"/>')],
             one_way, junction="100", link=link10),
        road("2", 70.0, [geometry(0, 60.0 + r, r, math.pi / 2, 70.0, "<line/>")], TWO_LANES, link=link2),
        conn)


@pytest.mark.parametrize("route", ["#1,10,2", "#1,2", ""])
def test_a_route_through_a_junction_follows_every_road_and_marks_the_junction(route, tmp_path):
    path, root = _write(tmp_path, _junction_file())
    track = load_xodr(f"{path}{route}")
    assert track.description.endswith(f"roads 1 → 10 → 2: 2 and 1 oncoming lane(s), {track.length:.0f} m")
    (a, b), = track.intersections
    outer_arc = (30.0 + 3.5 + 1.625) * math.pi / 2  # the ego lane (−2, keep right) is outside the left turn
    assert a == pytest.approx(60.0, abs=0.01) and b - a == pytest.approx(outer_arc, abs=0.01)
    assert track.boundaries[1].kind_at(0.5 * (a + b)) == "none" and track.boundaries[1].kind_at(10.0) == "dashed_white"
    worst = map_errors(track, root, [("1", 1), ("10", 1), ("2", 1)])
    assert max(worst["dev"], worst["point"], worst["width"]) < 0.01 and worst["heading"] < 1e-3, worst


def test_a_road_driven_against_its_direction_uses_its_left_lanes(tmp_path):
    link1 = '<successor elementType="road" elementId="2" contactPoint="start"/>'
    link2 = '<predecessor elementType="road" elementId="1" contactPoint="end"/>'
    text = document(road("1", 50.0, [geometry(0, 0.0, 0.0, 0.0, 50.0, "<line/>")], TWO_LANES, link=link1),
                    road("2", 60.0, [geometry(0, 50.0, 0.0, 0.0, 60.0, '<arc curvature="0.01"/>')], TWO_LANES,
                         link=link2))
    path, root = _write(tmp_path, text)
    track = load_xodr(f"{path}#2,1")
    # the driven side's one lane, then the other side's two as oncoming lanes left of it
    assert len(track.lanes) == 3 and track.oncoming == 2 and track.ego_lane == 0
    assert [ln.width for ln in track.lanes] == pytest.approx([3.5, 3.5, 3.25])
    worst = map_errors(track, root, [("2", -1), ("1", -1)])
    assert max(worst["dev"], worst["point"], worst["width"]) < 0.01 and worst["heading"] < 1e-3, worst
