"""Two-way roads: oncoming lanes travel against the reference line, and the map answers in each lane's own
direction of travel; a pose is matched to a lane of its own direction."""

import math

import pytest

from tracks.presets import load_track
from tracks.semantic_map import TrackMap


@pytest.fixture(scope="module")
def road():
    return load_track("two-way@3")


def test_an_oncoming_lane_is_measured_left_of_its_own_travel(road) -> None:
    smap, lane = TrackMap(road), road.lanes[1]
    for s in (60.0, 400.0, 900.0):
        pose = road.start_pose(1, s)
        assert pose.yaw == pytest.approx(road.reference.heading_at(s) + math.pi)
        x, y = lane.position(s, 0.4)  # 0.4 m left of the oncoming driver = right of the reference line
        assert lane.local_coordinates(x, y) == pytest.approx((s, 0.4), abs=1e-6)
        moved = type(pose)(x, y, pose.yaw)
        assert smap.project(moved) == pytest.approx((1, s, 0.4), abs=1e-6)
        _, heading = smap.lane_point(moved)
        assert math.remainder(heading - pose.yaw, 2.0 * math.pi) == pytest.approx(0.0, abs=1e-9)
        k = road.reference.curvature_at(s)
        assert smap.lane_curvature(moved) == pytest.approx(-k / (1.0 - k * lane.offset_at(s)))


def test_a_car_pushed_over_the_centre_line_stays_on_its_own_side_of_the_map(road) -> None:
    smap = TrackMap(road)
    ego = road.start_pose(0, 500.0)
    over = road.lanes[1].position(500.0, 0.0)
    wrong_side = type(ego)(over[0], over[1], ego.yaw)  # in the oncoming lane, heading along the road
    c = smap.project(wrong_side)
    assert c.lane == 0 and c.l == pytest.approx(road.lanes[1].offset_at(500.0), abs=1e-6)
    assert smap.project(wrong_side, 1).l == pytest.approx(0.0, abs=1e-6)


def test_the_ego_lane_must_run_along_the_road(road) -> None:
    from tracks.road import Track

    with pytest.raises(ValueError, match="ego lane 1 out of range"):
        Track("t", 0, "t", road.reference, [3.4, 3.4], ["solid_white", "double_yellow", "solid_white"], road.right,
              road.left, ego_lane=1, oncoming=1)
    with pytest.raises(ValueError, match="at least one lane must run along"):
        Track("t", 0, "t", road.reference, [3.4], ["solid_white", "solid_white"], road.right, road.left, oncoming=1)
