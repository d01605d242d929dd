"""Tile streaming on a route that comes back alongside itself: the streamer reads the car's own station, so it never
moves the reference line's walk onto the other branch, and the semantic map keeps placing the car on its lane."""

import math

import pytest

from testbed.conditions import get_condition
from testbed.world import TileStreamer
from tests.tracks.opendrive.xodr_text import constant, document, geometry, road, section
from tracks.opendrive.load import load_xodr
from tracks.pose import Pose
from tracks.semantic_map import TrackMap

# One road driven north 60 m, around a block to the left, back east and then south 11.5 m east of its start:
# (length m, curvature 1/m) per record, from (0, 0) heading north.
_RECORDS = [(60.0, 0.0), (3 * math.pi, 1 / 6), (40.0, 0.0), (5 * math.pi, -1 / 10), (30.0, 0.0),
            (5 * math.pi, -1 / 10), (51.0, 0.0), (5 * math.pi, -1 / 10), (76.0, 0.0)]


def _returning_road(tmp_path) -> str:
    x, y, hdg, s, records = 0.0, 0.0, math.pi / 2, 0.0, []
    for length, k in _RECORDS:
        shape = "<line/>" if k == 0.0 else f'<arc curvature="{k}"/>'
        records.append(geometry(s, x, y, hdg, length, shape))
        if k == 0.0:
            x, y = x + length * math.cos(hdg), y + length * math.sin(hdg)
        else:
            end = hdg + k * length
            x, y = x + (math.sin(end) - math.sin(hdg)) / k, y - (math.cos(end) - math.cos(hdg)) / k
            hdg = end
        s += length
    path = tmp_path / "returning.xodr"
    path.write_text(document(road("1", s, records, [section(0.0, [constant(3.5)])])))
    return str(path)


def test_the_streamer_leaves_the_car_on_its_lane_where_the_route_returns_beside_it(tmp_path):
    track = load_xodr(_returning_road(tmp_path))
    smap, lane = TrackMap(track), track.ego_lane
    streamer = TileStreamer(track, get_condition("day").lighting)
    centre = track.lanes[lane]
    try:
        for s in range(5, 70):
            pose = Pose(*centre.position(float(s), 0.0), centre.heading_at(float(s)))
            streamer.update(pose)
            assert smap.project(pose, lane).s == pytest.approx(s, abs=1e-6)
            assert math.floor(s / track.tile_length) in streamer.loaded
    finally:
        streamer.close()
