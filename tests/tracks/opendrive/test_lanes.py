"""Routes by lane: the ego lane keeps right unless the spec names one, follows lane links and laneLinks through
junctions (direct ones too), is never a bidirectional lane, passes lanes that appear or vanish; namespaced files
read; a `<border>` lane is refused only on the route; `ld3 tracks routes` lists the drivable routes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from testbed.cli import main
from testbed.presets import TrackFileError, build_track
from tests.tracks.opendrive.xodr_text import constant, document, geometry, road, section
from tracks.opendrive.load import load_xodr
from tracks.pose import Pose
from tracks.semantic_map import TrackMap

LINE = [geometry(0, 0.0, 0.0, 0.0, 60.0, "<line/>")]
TWO_EACH_WAY = [section(0.0, [constant(3.5), constant(3.25)], [constant(3.5), constant(3.5)])]


def _path(tmp_path, text: str):
    path = tmp_path / "map.xodr"
    path.write_text(text)
    return path


def _ego_y(track, s: float) -> float:
    """The world y of the ego lane's centre at track arc length s."""
    return float(track.lanes[track.ego_lane].position(s, 0.0)[1])


def test_the_ego_lane_keeps_right_and_the_spec_can_name_another(tmp_path):
    path = _path(tmp_path, document(road("1", 60.0, LINE, TWO_EACH_WAY)))
    right = load_xodr(str(path))
    assert right.ego_lane == 0 and len(right.lanes) == 4 and right.oncoming == 2
    assert _ego_y(right, 30.0) == pytest.approx(-3.5 - 1.625, abs=1e-3)
    inner = load_xodr(f"{path}#1@-1")
    assert inner.ego_lane == 1 and _ego_y(inner, 30.0) == pytest.approx(-1.75, abs=1e-3)


def _fork(r: float = 20.0) -> str:
    """Road 1 (lanes −1, −2) → junction 100: connecting road 11 runs straight on from lane −1 only into road 3,
    connecting road 10 turns right (radius `r`, its lane's centre r − 1.75 m) from lane −2 into road 2."""
    conn = ('<junction id="100">'
            '<connection id="0" incomingRoad="1" connectingRoad="11" contactPoint="start">'
            '<laneLink from="-1" to="-1"/></connection>'
            '<connection id="1" incomingRoad="1" connectingRoad="10" contactPoint="start">'
            '<laneLink from="-2" to="-1"/></connection></junction>')
    into = '<predecessor elementType="road" elementId="1" contactPoint="end"/>'
    one = [section(0.0, [constant(3.5)])]
    return document(
        road("1", 60.0, LINE, [section(0.0, [constant(3.5), constant(3.5)])],
             link='<successor elementType="junction" elementId="100"/>'),
        road("11", 20.0, [geometry(0, 60.0, 0.0, 0.0, 20.0, "<line/>")], one, junction="100",
             link=into + '<successor elementType="road" elementId="3" contactPoint="start"/>'),
        road("3", 40.0, [geometry(0, 80.0, 0.0, 0.0, 40.0, "<line/>")], one,
             link='<predecessor elementType="junction" elementId="100"/>'),
        road("10", r * math.pi / 2, [geometry(0, 60.0, -3.5, 0.0, r * math.pi / 2, f'<arc curvature="{-1 / r}"/>')],
             one, junction="100", link=into + '<successor elementType="road" elementId="2" contactPoint="start"/>'),
        road("2", 40.0, [geometry(0, 60.0 + r, -3.5 - r, -math.pi / 2, 40.0, "<line/>")], one,
             link='<predecessor elementType="junction" elementId="100"/>'),
        conn)


def test_the_default_route_follows_the_ego_lane_s_lane_link_not_the_straightest_road(tmp_path):
    path = _path(tmp_path, _fork())
    track = load_xodr(str(path))  # keep right: lane −2, which only the right turn carries
    assert " roads 1 → 10 → 2:" in track.description
    inner = load_xodr(f"{path}#@-1")  # the inner lane goes straight on
    assert " roads 1 → 11 → 3:" in inner.description


def test_a_lane_tighter_than_a_car_follows_ends_the_default_route_and_refuses_a_route_through_it(tmp_path):
    path = _path(tmp_path, _fork(r=4.0))  # lane −2's only way on turns at a radius of 2.25 m
    track = load_xodr(str(path))
    assert " roads 1:" in track.description
    with pytest.raises(TrackFileError, match=r"^[^\n]*radius of 2\.25 m on road 10, tighter than the 3 m"):
        build_track(f"xodr:{path}#1,10,2")


def test_a_bidirectional_lane_is_never_the_ego_lane(tmp_path):
    lanes = section(0.0, [constant(3.0), constant(3.5)], [constant(3.5)])
    lanes = lanes.replace('<lane id="-1" type="driving"', '<lane id="-1" type="bidirectional"')
    path = _path(tmp_path, document(road("1", 60.0, LINE, [lanes])))
    track = load_xodr(str(path))
    assert len(track.lanes) == 1 and track.oncoming == 0 and track.lanes[0].width == pytest.approx(3.5)
    assert _ego_y(track, 30.0) == pytest.approx(-3.0 - 1.75, abs=1e-3)
    assert track.left.paved == pytest.approx(3.0 + 3.5)  # the turn lane and the other side are paved surface
    with pytest.raises(TrackFileError, match="lane -1 is not a drivable lane of the driving direction"):
        build_track(f"xodr:{path}#1@-1")


def test_a_direct_junction_joins_its_roads(tmp_path):
    lanes = [section(0.0, [constant(3.5)], [constant(3.5)])]
    text = document(
        road("1", 60.0, LINE, lanes, link='<successor elementType="junction" elementId="9"/>'),
        road("2", 50.0, [geometry(0, 60.0, 0.0, 0.0, 50.0, "<line/>")], lanes,
             link='<predecessor elementType="junction" elementId="9"/>'),
        '<junction id="9" type="direct"><connection id="0" incomingRoad="1" linkedRoad="2" contactPoint="start">'
        '<laneLink from="-1" to="-1"/></connection></junction>', minor=7)
    path = _path(tmp_path, text)
    for spec in ("", "#1,2"):
        track = load_xodr(f"{path}{spec}")
        assert " roads 1 → 2:" in track.description and track.length == pytest.approx(110.0, abs=0.01)
        assert not track.intersections


def test_the_ego_lane_follows_its_link_past_a_lane_appearing_next_to_the_centre_line(tmp_path):
    grow = [(0.0, (0.0, 0.0, 3 * 3.5 / 60**2, -2 * 3.5 / 60**3))]  # 0 → 3.5 m over 60 m, next to the centre line
    first = section(0.0, [constant(3.5)], [constant(3.5)])
    second = section(60.0, [grow, constant(3.5)], [constant(3.5)])
    # lane −1 of the first section goes on as lane −2 of the second
    first = first.replace('<lane id="-1" type="driving">', '<lane id="-1" type="driving"><link><successor id="-2"/>'
                          '</link>')
    path = _path(tmp_path, document(road("1", 120.0, [geometry(0, 0.0, 0.0, 0.0, 120.0, "<line/>")],
                                         [first, second])))
    track = load_xodr(str(path))
    assert len(track.lanes) - track.oncoming == 1
    for s in np.linspace(1.0, track.length - 1.0, 40):
        x, y = track.lanes[track.ego_lane].position(s, 0.0)
        u = max(x - 60.0, 0.0)
        inner = 3 * 3.5 / 60**2 * u**2 - 2 * 3.5 / 60**3 * u**3  # the appearing lane's width there
        assert y == pytest.approx(-inner - 1.75, abs=0.005)


def test_a_vanishing_lane_is_not_chosen_by_keep_right(tmp_path):
    shrink = [(0.0, (3.5, 0.0, -3 * 3.5 / 60**2, 2 * 3.5 / 60**3))]  # 3.5 → 0 m over the section
    path = _path(tmp_path, document(road("1", 60.0, LINE, [section(0.0, [constant(3.5), shrink])])))
    track = load_xodr(str(path))
    assert _ego_y(track, 30.0) == pytest.approx(-1.75, abs=1e-3)
    with pytest.raises(TrackFileError, match=r"road 1 <laneSection s=0>: the ego lane -2 ends there \(width 0.00 m\)"):
        build_track(f"xodr:{path}#@-2")


def test_a_file_with_a_default_namespace_reads(tmp_path):
    text = document(road("1", 60.0, LINE, TWO_EACH_WAY)).replace(
        "<OpenDRIVE>", '<OpenDRIVE xmlns="http://code.asam.net/simulation/standard/opendrive_schema">')
    track = load_xodr(str(_path(tmp_path, text)))
    assert len(track.lanes) == 4 and track.length == pytest.approx(60.0, abs=0.01)


def test_a_border_lane_is_refused_only_where_the_route_needs_it(tmp_path):
    bordered = section(0.0, [constant(3.5)]).replace("<width", "<border")
    text = document(road("1", 60.0, LINE, [section(0.0, [constant(3.5)])]),
                    road("2", 60.0, [geometry(0, 0.0, 30.0, 0.0, 60.0, "<line/>")], [bordered]))
    path = _path(tmp_path, text)
    assert load_xodr(f"{path}#1").length == pytest.approx(60.0, abs=0.01)
    with pytest.raises(TrackFileError) as info:
        build_track(f"xodr:{path}#2")
    assert str(info.value) == (f"{path}: road 2 <laneSection s=0> lane -1: <border> is not supported "
                               f"(describe the lane by <width>)")


def test_tracks_routes_lists_every_drivable_route_and_each_loads(tmp_path, capsys):
    path = _path(tmp_path, _fork())
    assert main(["tracks", "routes", f"xodr:{path}"]) == 0
    lines = capsys.readouterr().out.splitlines()
    specs = [line.split()[0] for line in lines]
    assert specs[0] == f"xodr:{path}#1,10,2@-2"
    for spec in specs:
        track = build_track(spec)
        smap = TrackMap(track)
        x, y = track.lanes[track.ego_lane].position(track.length / 2, 0.0)
        heading = track.reference.heading_at(track.length / 2)
        assert abs(smap.lane_dev(Pose(float(x), float(y), heading), track.ego_lane)) < 1e-3
