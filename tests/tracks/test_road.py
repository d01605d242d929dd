import math

import numpy as np
import pytest

from tracks.obstacles import road_obstacles
from tracks.presets import load_track


def test_surface_and_edge_kind_on_the_slr_drop_off():
    track = load_track("slr")
    lo, hi = track.paved_range
    assert track.road_surface_contains(500.0, 0.0)
    assert track.road_surface_contains(500.0, lo + 0.05)
    assert track.edge_kind_at(500.0, 0.0) is None
    assert not track.road_surface_contains(500.0, lo - 0.05)
    assert track.edge_kind_at(500.0, lo - 0.05) == "drop_off"
    assert track.edge_kind_at(500.0, hi + 1.0) == "drop_off"
    assert track.edge_kind_at(-10.0, 0.0) == "open"


def test_intersections_widen_the_surface_and_have_no_markings_or_curbs():
    track = load_track("local")
    a, b = track.intersections[0]
    mid = 0.5 * (a + b)
    x, y = track.reference.point(mid, track.paved_range[1] + 2.0)
    assert track.road_surface_contains(x, y)
    x, y = track.reference.point(a - 5.0, track.paved_range[1] + 2.0)
    assert not track.road_surface_contains(x, y)
    assert all(bd.kind_at(mid) == "none" for bd in track.boundaries)
    assert track.boundaries[1].kind_at(a - 5.0) == "dashed_white"
    tile = int(mid // track.tile_length)
    for box in road_obstacles(track, tile):
        s, _ = track.reference.project(box.center[0], box.center[1])
        assert not a < s < b


def test_obstacle_chunks_follow_the_curve_within_tiles():
    track = load_track("urban-curvy")
    curbs = [b for b in road_obstacles(track) if b.kind == "curb"]
    t_curb = track.boundaries[0].t - 0.10 - 0.15
    for box in curbs[::7]:
        s, t = track.reference.project(box.center[0], box.center[1])
        assert t == pytest.approx(t_curb, abs=0.025)
        assert box.tile * track.tile_length - 0.5 <= s <= (box.tile + 1) * track.tile_length + 0.5
        assert box.center[2] == pytest.approx(0.075) and box.half_extents[2] == pytest.approx(0.075)
        assert box.half_extents[0] <= 0.5 * track.tile_length + 0.05
    assert max(b.half_extents[0] for b in curbs) > 5.0  # long chunks on the straights


def test_urban_straight_trees_sit_beyond_the_curb():
    track = load_track("urban-straight")
    trees = [b for b in road_obstacles(track) if b.kind == "tree"]
    assert len(trees) > 100
    near = [track.reference.project(b.center[0], b.center[1])[1] + b.half_extents[1] for b in trees]
    np.testing.assert_allclose(near, track.boundaries[0].t - 0.85, atol=1e-6)


def test_tiles_near_covers_the_radius():
    track = load_track("highway")
    x, y = track.reference.point(1000.0)
    tiles = track.tiles_near(x, y, 60.0)
    assert tiles == list(range(47, 53))
    assert track.tiles_near(*track.reference.point(5.0), 30.0) == [0, 1]


def test_lane_curvature_of_offset_lanes():
    track = load_track("highway")
    s = next(s for s in track.reference.s if abs(track.reference.curvature_at(s)) > 1e-3)
    k = track.reference.curvature_at(s)
    left, right = track.lanes[2], track.lanes[0]
    assert left.curvature_at(s) == pytest.approx(1.0 / (1.0 / k - 3.75))
    assert right.curvature_at(s) == pytest.approx(1.0 / (1.0 / k + 3.75))
    assert math.copysign(1.0, left.curvature_at(s)) == math.copysign(1.0, k)


@pytest.mark.parametrize("name", ["urban-curvy", "highway", "local", "slr"])
def test_a_disc_the_surface_holds_has_every_point_on_the_surface(name):
    track = load_track(name)
    rng = np.random.default_rng(4)
    lo, hi = track.paved_range
    held = 0
    for _ in range(300):
        s, t, radius = rng.uniform(0.0, track.length), rng.uniform(lo - 1.0, hi + 1.0), rng.uniform(0.3, 1.5)
        x, y = track.reference.point(s, t)
        if not track.surface_holds_disc(x, y, radius):
            continue
        held += 1
        ang, r = rng.uniform(-math.pi, math.pi, 24), radius * np.sqrt(rng.uniform(0.0, 1.0, 24))
        ring = [(x + radius * math.cos(a), y + radius * math.sin(a)) for a in np.linspace(-math.pi, math.pi, 24)]
        inside = [(x + rk * math.cos(a), y + rk * math.sin(a)) for a, rk in zip(ang, r, strict=True)]
        assert all(track.road_surface_contains(px, py) for px, py in ring + inside)
    assert held > 30  # the shortcut applies on a good share of the road
