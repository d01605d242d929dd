import math

import numpy as np
import pytest

from tracks.obstacles import road_obstacles
from tracks.presets import list_presets, load_track

STRADDLE = {"slr": (3.56, 0.83), "urban-straight": (3.90, 1.00), "urban-curvy": (3.40, 0.75)}
EGO = {"slr": 0, "urban-straight": 0, "urban-curvy": 0, "highway": 1, "local": 0, "parking-lot": 0, "two-way": 0}
MIN_LENGTH = {
    "slr": 1500,
    "urban-straight": 1500,
    "urban-curvy": 1500,
    "highway": 3000,
    "local": 1500,
    "parking-lot": 80,
    "two-way": 1400,
}


def test_list_presets_names_every_family():
    names = [name for name, _ in list_presets()]
    assert names == list(EGO)
    assert all(desc for _, desc in list_presets())


@pytest.mark.parametrize(
    "spec", ["slr", "urban-straight@3", "urban-curvy@7", "highway@2", "local@5", "parking-lot", "two-way@4"]
)
def test_presets_load_with_their_ego_lane_length_and_run_in(spec):
    track = load_track(spec)
    assert track.ego_lane == EGO[track.name]
    assert track.length >= MIN_LENGTH[track.name]
    run_in = 80.0 if track.name == "parking-lot" else 100.0
    assert np.all(track.reference.curvature[track.reference.s <= run_in] == 0.0)
    assert not track.intersections or track.intersections[0][0] > run_in


@pytest.mark.parametrize("name", list(STRADDLE))
@pytest.mark.parametrize("seed", [0, 1, 9])
def test_lane_widths_give_the_paper_straddle_deviations(name, seed):
    width, straddle = STRADDLE[name]
    track = load_track(f"{name}@{seed}")
    assert track.lanes[track.ego_lane].width == pytest.approx(width)
    assert track.lane_straddle_dev() == pytest.approx(straddle)


@pytest.mark.parametrize("seed", [0, 1, 4])
def test_curvature_limits(seed):
    curvy = load_track(f"urban-curvy@{seed}")
    r_min = 1.0 / np.abs(curvy.reference.curvature).max()
    assert 60.0 - 1e-6 <= r_min <= 66.0
    highway = load_track(f"highway@{seed}")
    assert 1.0 / np.abs(highway.reference.curvature).max() >= 600.0 - 1e-6
    assert [ln.width for ln in highway.lanes] == [3.75] * 3


@pytest.mark.parametrize("seed", [0, 3])
def test_local_has_intersections_every_few_hundred_metres(seed):
    track = load_track(f"local@{seed}")
    starts = np.array([a for a, _ in track.intersections])
    assert len(starts) >= 4
    assert np.all((np.diff(starts) > 150.0) & (np.diff(starts) < 450.0))
    assert all(3.0 <= ln.width <= 3.5 for ln in track.lanes)
    assert all(track.reference.curvature_at(s) == 0.0 for a, b in track.intersections for s in (a, b))


def test_urban_curvy_has_the_divider_left_and_curb_right():
    track = load_track("urban-curvy")
    assert track.left.kind == "divider" and track.right.kind == "curb"
    left_line = track.boundaries[-1].t
    div = [b for b in road_obstacles(track, 10) if b.kind == "divider"]
    curbs = [b for b in road_obstacles(track, 10) if b.kind == "curb"]
    assert div and curbs
    for box in div:
        _s, t = track.reference.project(box.center[0], box.center[1])
        assert t - box.half_extents[1] == pytest.approx(left_line + 0.15, abs=0.03)
    assert all(track.reference.project(b.center[0], b.center[1])[1] < 0.0 for b in curbs)


def test_seed_varies_geometry_and_is_repeatable():
    a, b, c = load_track("urban-curvy@7"), load_track("urban-curvy@7"), load_track("urban-curvy@8")
    np.testing.assert_array_equal(a.reference.x, b.reference.x)
    assert a.length != c.length
    assert a.lidar_feature_quality(500.0) == b.lidar_feature_quality(500.0)


def test_lidar_feature_quality_is_a_smooth_profile_in_unit_range():
    track = load_track("highway@1")
    q = np.array([track.lidar_feature_quality(s) for s in np.arange(0.0, track.length, 1.0)])
    assert q.min() >= 0.0 and q.max() <= 1.0
    assert q.max() - q.min() > 0.2  # it has feature-poor stretches
    assert np.abs(np.diff(q)).max() < 0.05  # and no jumps between metres


@pytest.mark.parametrize("spec", ["nowhere", "slr@", "slr@-1", "slr@x", "slr@1.5"])
def test_bad_specs_raise_one_line_value_errors(spec):
    with pytest.raises(ValueError) as err:
        load_track(spec)
    assert "\n" not in str(err.value)


def test_start_pose_sits_on_the_lane_centre():
    track = load_track("highway")
    pose = track.start_pose()
    lane = track.lanes[1]
    assert lane.local_coordinates(pose.x, pose.y) == pytest.approx((20.0, 0.0), abs=1e-9)
    assert pose.yaw == pytest.approx(lane.heading_at(20.0))
    assert math.isclose(track.start_pose(lane=0, s=50.0).y, -3.75, abs_tol=1e-9)


@pytest.mark.parametrize("seed", [0, 2, 8])
def test_two_way_has_one_oncoming_lane_beyond_a_double_yellow_centre_line(seed):
    track = load_track(f"two-way@{seed}")
    assert [ln.direction for ln in track.lanes] == [1, -1] and track.oncoming == 1
    assert [b.runs[0].kind for b in track.boundaries] == ["solid_white", "double_yellow", "solid_white"]
    assert track.lanes[0].width == pytest.approx(3.40)
    assert 1.0 / track.max_abs_curvature >= 150.0 - 1e-6
