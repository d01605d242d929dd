"""The compiled planner plans to the bit as the pure-Python planner does on every preset's lanes: drives along
each lane at speeds from standing to 35 m/s (previews of one to several steps), wandering off the centre and
heading, into the road's end (the preview walks off it), off the map (the held plan) and through a non-finite
pose, with the loop's other map questions between the plans, so the map's memo and walk see the same history."""

import numpy as np
import pytest

from testbed.control.planner import LanePlanner
from tests.tracks.test_map_kernels import asked, bits, pure_map
from tracks.compiled import compiled_module
from tracks.pose import Pose
from tracks.presets import PRESETS, load_track
from tracks.semantic_map import TrackMap

KERNELS = compiled_module("testbed.control.planner_kernels")
compiled = pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")


def plan_bits(planner: LanePlanner, pose: Pose, speed: float, t: float) -> object:
    p = planner.plan(pose, speed, t)
    return bits((p.lateral_error, p.heading_error, p.curvature, p.target_speed, p.target_accel,
                 p.local_curvature)), p.off_map


def drive(spec: str, lane: int, seed: int) -> list[tuple[Pose, Pose, float]]:
    """(control pose, true pose, speed) along `lane` from near its start to 8 m past the road's end, with
    off-map and non-finite control poses now and then."""
    track, rng = load_track(spec), np.random.default_rng(seed)
    ln, length = track.lanes[lane], track.reference.length
    s_values = np.linspace(length - 25.0, length + 8.0, 60) if ln.direction > 0 else np.linspace(25.0, -8.0, 60)
    s_values = np.concatenate([rng.uniform(0.0, length, 240), s_values])
    out = []
    for k, s in enumerate(s_values):
        x, y = ln.position(float(np.clip(s, 0.0, length)), float(rng.normal(0.0, 0.6)))
        yaw = ln.heading_at(float(s)) + float(rng.normal(0.0, 0.1))
        true = Pose(x, y, yaw)
        pose = Pose(x + float(rng.normal(0.0, 0.3)), y + float(rng.normal(0.0, 0.3)), yaw)
        if k % 37 == 5:
            pose = Pose(x + 80.0, y - 80.0, yaw)
        if k % 91 == 7:
            pose = Pose(x, float("nan"), yaw)
        out.append((pose, true, float(rng.uniform(0.0, 35.0))))
    return out


@compiled
@pytest.mark.parametrize("spec", [*PRESETS, "urban-curvy@101", "highway@7"])
def test_the_compiled_planner_plans_as_the_python_reference(spec):
    for lane in range(len(load_track(spec).lanes)):
        smap, pure = TrackMap(load_track(spec)), pure_map(spec)
        fast, slow = LanePlanner(smap, lane, 20.0), LanePlanner(pure, lane, 20.0)
        assert fast._kernel is not None and slow._kernel is None
        for k, (pose, true, speed) in enumerate(drive(spec, lane, seed=lane + len(spec))):
            if k == 200:
                fast.start_stop(k * 0.01, speed)
                slow.start_stop(k * 0.01, speed)
            assert plan_bits(fast, pose, speed, k * 0.01) == plan_bits(slow, pose, speed, k * 0.01), (k, pose)
            # the loop's other questions: the true pose's deviation, the pose's lane point
            assert asked(smap, "lane_dev", true, lane) == asked(pure, "lane_dev", true, lane)
            assert asked(smap, "lane_point", pose, None) == asked(pure, "lane_point", pose, None)
            hint = pure.track.reference._hint
            assert smap.track.reference._kernel.hint == (-1 if hint is None else hint)


@compiled
def test_a_lane_the_road_does_not_have_is_refused_as_in_python():
    smap, pure = TrackMap(load_track("highway")), pure_map("highway")
    for m in (smap, pure):
        with pytest.raises(ValueError, match="lane 9 not on highway"):
            LanePlanner(m, 9, 20.0).plan(Pose(100.0, 0.0, 0.0), 20.0, 0.0)


@compiled
@pytest.mark.parametrize("spec", [*PRESETS, "urban-curvy@101"])
def test_the_compiled_curves_ahead_are_the_python_ones(spec):
    for lane in range(len(load_track(spec).lanes)):
        fast, slow = LanePlanner(TrackMap(load_track(spec)), lane, 20.0), LanePlanner(pure_map(spec), lane, 20.0)
        for pose, _, _ in drive(spec, lane, seed=3)[::20]:
            (d_fast, v_fast), (d_slow, v_slow) = fast._curves_ahead(pose), slow._curves_ahead(pose)
            assert (d_fast.tobytes(), v_fast.tobytes()) == (d_slow.tobytes(), v_slow.tobytes()), pose


@compiled
@pytest.mark.parametrize("spec", ["urban-curvy@101", "urban-curvy@3", "highway@7"])
def test_the_compiled_curve_limit_is_the_python_one(spec):
    """The curve limit alone (both planners on the compiled map): random speeds (standing, reversing), times that
    step back now and then, a cruise speed changed mid-drive, samples every CURVE_PERIOD and the travel between."""
    smap, rng = TrackMap(load_track(spec)), np.random.default_rng(11)
    fast, slow = LanePlanner(smap, 0, 20.0), LanePlanner(smap, 0, 20.0)
    slow._limit = None
    assert fast._limit is not None
    t, limits = 0.0, 0
    for k, (pose, _, speed) in enumerate(drive(spec, 0, seed=5)):
        t += float(rng.choice([0.025, 0.01, -0.02, 0.1]))
        speed = float(rng.choice([speed, -1.0, 0.0]))
        if k == 150:
            fast.cruise_speed = slow.cruise_speed = 8.0
        a, b = fast._curve_limit(pose, speed, t), slow._curve_limit(pose, speed, t)
        fast._t_last = slow._t_last = t
        assert bits((a,)) == bits((b,)), (k, a, b)
        limits += np.isfinite(a)
    assert limits > 20  # curves bound the speed on these roads
