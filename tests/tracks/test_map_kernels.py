"""The compiled semantic map answers `project`, `lane_dev`, `lane_width`, `lane_point`, `lane_curvature` and
`is_intersection` to the bit as the pure-Python map does, with the same errors, on every preset's lanes (both
directions on a two-way road): along the lanes at random offsets and headings, asked again (the memo), beyond
the ends, far off, not finite, and about a lane the road does not have; the reference line's walk is left in the
same state."""

import os
import pickle
import shutil
import struct
import subprocess
import sys

import numpy as np
import pytest

from tracks.compiled import compiled_module
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.presets import PRESETS, load_track
from tracks.recent import RecentAnswers
from tracks.semantic_map import TrackMap

KERNELS = compiled_module("tracks.map_kernels")
compiled = pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")


def pure_map(spec: str) -> TrackMap:
    """A cold map of the track answering with the pure-Python methods only."""
    smap = TrackMap(load_track(spec))
    line = smap.track.reference
    smap.compiled, line._kernel, line._hint, line._memo = None, None, None, RecentAnswers(16)
    return smap


def bits(answer: object) -> object:
    """An answer with every float as its bytes (0.0 and -0.0 differ), arrays as lists."""
    if isinstance(answer, np.ndarray):
        answer = answer.tolist()
    if isinstance(answer, tuple | list):
        return type(answer).__name__, [bits(a) for a in answer]
    if isinstance(answer, float):
        return struct.pack("<d", answer)
    return answer


def asked(smap: TrackMap, method: str, *args: object) -> object:
    try:
        return bits(getattr(smap, method)(*args))
    except (OffMapError, ValueError) as err:
        return type(err).__name__, str(err)


def questions(spec: str, n: int, seed: int) -> list[tuple[Pose, int | None]]:
    """Poses along every lane (heading of travel, turned by up to ±0.5 rad, some backwards), 2 m beyond either
    end, far off and not finite, each about its lane, no lane or every lane; some asked again."""
    track, rng = load_track(spec), np.random.default_rng(seed)
    length, lanes = track.reference.length, len(track.lanes)
    out: list[tuple[Pose, int | None]] = []
    for k in range(n):
        lane = track.lanes[k % lanes]
        s = float(rng.uniform(-20.0, length + 20.0)) if k % 11 == 0 else float(rng.uniform(0.0, length))
        x, y = lane.position(float(np.clip(s, 0.0, length)), float(rng.normal(0.0, 1.5)))
        yaw = lane.heading_at(s) + float(rng.uniform(-0.5, 0.5)) + (np.pi if k % 17 == 0 else 0.0)
        if k % 29 == 0:
            x, y = x + float(rng.uniform(-60.0, 60.0)), y + float(rng.uniform(-60.0, 60.0))
        pose = Pose(x, y, yaw)
        if k % 97 == 0:
            pose = Pose(float("nan"), y, yaw) if k % 2 else Pose(x, y, float("inf"))
        ask = (k % (lanes + 2)) - 1  # None (-1), every lane, and one the road does not have
        out.append((pose, None if ask < 0 else ask))
        if k % 5 == 0 and k > 3:
            out.append(out[k - 3])  # asked again (from the memo, or not, as the Python map would)
    return out


def test_the_kernel_is_built_where_a_c_compiler_is():
    if shutil.which("cc") is not None or shutil.which("gcc") is not None:
        assert KERNELS is not None, "reinstall (pip install -e .) to build the kernels"


@compiled
@pytest.mark.parametrize("spec", [*PRESETS, "urban-curvy@101", "highway@7", "two-way@3"])
def test_map_kernel_answers_as_the_python_reference(spec):
    smap, pure = TrackMap(load_track(spec)), pure_map(spec)
    assert smap.compiled is not None
    for pose, lane in questions(spec, 1200, seed=len(spec)):
        for method in ("project", "lane_dev", "lane_width", "lane_point", "lane_curvature"):
            assert asked(smap, method, pose, lane) == asked(pure, method, pose, lane), (method, pose, lane)
        assert asked(smap, "is_intersection", pose) == asked(pure, "is_intersection", pose)
        hint = pure.track.reference._hint
        assert smap.track.reference._kernel.hint == (-1 if hint is None else hint)


@compiled
def test_points_beyond_the_kernels_reach_are_answered_and_kept_as_in_python():
    smap, pure = TrackMap(load_track("highway")), pure_map("highway")
    for pose in (Pose(2e9, 0.0, 0.0), Pose(100.0, 0.0, 0.0), Pose(2e9, 0.0, 0.0), Pose(-3e9, 5e9, 1.0)):
        assert asked(smap, "project", pose, 0) == asked(pure, "project", pose, 0)
        assert smap.track.reference.project(pose.x, pose.y) == pure.track.reference.project(pose.x, pose.y)


@compiled
def test_a_map_with_its_kernel_pickles():
    smap = TrackMap(load_track("urban-curvy"))
    copied = pickle.loads(pickle.dumps(smap))
    pose = Pose(120.0, 3.0, 0.2)
    assert bits(copied.lane_point(pose, 0)) == bits(smap.lane_point(pose, 0))


def test_lanes_with_width_profiles_are_answered_by_python():
    from tracks.profile import Profile

    track = load_track("highway")
    for lane in track.lanes:
        lane.profiles = (Profile(np.array([0.0, track.length]), np.array([lane.offset, lane.offset + 0.2])),
                         Profile(np.array([0.0, track.length]), np.array([lane.width, lane.width - 0.2])))
    assert TrackMap(track).compiled is None


def test_ld3_compiled_0_keeps_every_kernel_off():
    code = ("from testbed.control.planner import LanePlanner; from tracks.presets import load_track; "
            "from tracks.semantic_map import TrackMap; m = TrackMap(load_track('highway')); "
            "assert m.compiled is None and m.track.reference._kernel is None; "
            "assert LanePlanner(m, 0, 10.0)._kernel is None")
    env = {**os.environ, "LD3_COMPILED": "0"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, cwd=os.path.dirname(os.path.dirname(
        os.path.dirname(os.path.abspath(__file__)))))
