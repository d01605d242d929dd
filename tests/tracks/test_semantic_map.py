import inspect
import math

import numpy as np
import pytest

from tracks.bench import map_query_benchmark
from tracks.geometry import Arc, ReferenceLine, Straight
from tracks.layout import Edge
from tracks.map_api import OffMapError, SemanticMap
from tracks.pose import Pose
from tracks.presets import load_track
from tracks.road import Track
from tracks.semantic_map import TrackMap


@pytest.fixture(scope="module")
def two_lane_arc() -> Track:
    edge = Edge("shoulder", paved=1.0, ground="grass")
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(150.0), Arc(100.0, 150.0), Straight(100.0)])
    return Track(
        "test",
        0,
        "test road",
        ref,
        [3.5, 3.0],
        ["solid_white", "dashed_white", "solid_white"],
        edge,
        edge,
        ego_lane=0,
        intersections=[(50.0, 70.0)],
    )


def test_trackmap_matches_the_protocol_signatures():
    for name in ("project", "lane_dev", "lane_width", "lane_point", "lane_curvature", "is_intersection"):
        mine = inspect.signature(getattr(TrackMap, name))
        spec = inspect.signature(getattr(SemanticMap, name))
        assert list(mine.parameters) == list(spec.parameters)
        assert [p.default for p in mine.parameters.values()] == [p.default for p in spec.parameters.values()]


def test_lane_dev_is_positive_left_negative_right(two_lane_arc):
    m = TrackMap(two_lane_arc)
    assert m.lane_dev(Pose(30.0, 0.4, 0.0)) == pytest.approx(0.4)
    assert m.lane_dev(Pose(30.0, -0.6, 0.0)) == pytest.approx(-0.6)
    # on the left-turning arc the centre of curvature is to the left: a point nearer the centre is + left
    lane0 = two_lane_arc.lanes[0]
    x, y = lane0.position(220.0, 0.7)
    assert m.lane_dev(Pose(x, y, 0.0)) == pytest.approx(0.7, abs=1e-6)
    assert m.lane_curvature(Pose(x, y, 0.0)) == pytest.approx(1.0 / 100.0)


def test_nearest_lane_and_requested_lane(two_lane_arc):
    m = TrackMap(two_lane_arc)
    pose = Pose(30.0, 3.5, 0.0)  # lane 1 spans t in [1.75, 4.75], centre 3.25
    c = m.project(pose)
    assert c.lane == 1 and c.l == pytest.approx(0.25)
    assert m.lane_dev(pose, lane=0) == pytest.approx(3.5)
    assert m.lane_width(pose) == pytest.approx(3.0)
    assert m.lane_width(Pose(30.0, 0.0, 0.0)) == pytest.approx(3.5)
    point, heading = m.lane_point(pose)
    np.testing.assert_allclose(point, [30.0, 3.25], atol=1e-9)
    assert heading == pytest.approx(0.0)


def test_lane_point_on_the_arc(two_lane_arc):
    m = TrackMap(two_lane_arc)
    lane1 = two_lane_arc.lanes[1]
    x, y = lane1.position(200.0, -0.5)
    point, heading = m.lane_point(Pose(x, y, 1.0), lane=1)
    np.testing.assert_allclose(point, lane1.position(200.0), atol=1e-6)
    assert heading == pytest.approx(50.0 / 100.0)


def test_intersections_are_flagged(two_lane_arc):
    m = TrackMap(two_lane_arc)
    assert m.is_intersection(Pose(60.0, 0.0, 0.0))
    assert not m.is_intersection(Pose(49.0, 0.0, 0.0))
    assert not m.is_intersection(Pose(71.0, 0.0, 0.0))


@pytest.mark.parametrize(
    "pose",
    [
        Pose(math.nan, 0.0, 0.0),
        Pose(10.0, math.inf, 0.0),
        Pose(10.0, 0.0, math.nan),
        Pose(30.0, -1.75 - 3.01, 0.0),
        Pose(30.0, 4.75 + 3.01, 0.0),
        Pose(-5.0, 0.0, 0.0),
        Pose(5000.0, 9000.0, 0.0),
    ],
)
def test_off_map_raises(two_lane_arc, pose):
    with pytest.raises(OffMapError):
        TrackMap(two_lane_arc).lane_dev(pose)


def test_just_inside_the_margin_is_on_map(two_lane_arc):
    assert TrackMap(two_lane_arc).lane_dev(Pose(30.0, -1.75 - 2.9, 0.0)) == pytest.approx(-4.65)


def test_unknown_lane_index_raises(two_lane_arc):
    with pytest.raises(ValueError):
        TrackMap(two_lane_arc).lane_dev(Pose(30.0, 0.0, 0.0), lane=2)


def test_query_benchmark_reports_fast_queries():
    result = map_query_benchmark(load_track("urban-curvy"), n=3000)
    assert set(result) >= {"median_us", "p99_us"}
    assert 0.0 < result["median_us"] < 60.0  # target 20 µs on an idle core; loose bound for a shared CI box


def test_repeated_queries_answer_as_a_cold_map_and_errors_are_not_kept(two_lane_arc):
    warm, poses = TrackMap(two_lane_arc), [Pose(30.0 + 3.0 * k, 1.0 + 0.2 * k, 0.1) for k in range(12)]
    answers = [warm.project(poses[k % 12], lane) for k in range(60) for lane in (None, 0, 1)]
    cold = [TrackMap(two_lane_arc).project(poses[k % 12], lane) for k in range(60) for lane in (None, 0, 1)]
    assert answers == cold
    nan = Pose(30.0, 1.0, math.nan)
    for _ in range(2):
        with pytest.raises(OffMapError):
            warm.project(nan)
    with pytest.raises(ValueError):
        warm.project(poses[0], 7)


@pytest.mark.parametrize("name", ["urban-curvy", "highway", "local", "parking-lot", "two-way"])
def test_a_lanes_centre_is_its_position_and_heading_to_the_bit(name):
    track = load_track(name)
    for lane in track.lanes:
        for s in [-3.0, 0.0, *np.linspace(0.0, track.length, 401).tolist(), track.length + 2.5]:
            assert lane.centre_at(s) == (*lane.position(s, 0.0), lane.heading_at(s))
