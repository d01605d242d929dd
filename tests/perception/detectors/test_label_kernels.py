"""The compiled line fit (testbed/perception/detectors/label_kernels.pyx) gives the map's true ego lines to the bit
as the pure-Python path does, on every preset and two held-out layouts: poses along and across the lanes, yawed, near
and beyond the road's ends (lines carried on straight, lines that do not cross x = 0 beside the car), and a car
turned across the road."""

import shutil

import numpy as np
import pytest

from testbed.perception.detectors import labels
from tracks.compiled import compiled_module
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.presets import PRESETS, load_track

KERNELS = compiled_module("testbed.perception.detectors.label_kernels")
compiled = pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")


def test_the_kernel_is_built_where_a_c_compiler_is():
    if shutil.which("cc") is not None or shutil.which("gcc") is not None:
        assert KERNELS is not None, "reinstall (pip install -e .) to build the kernels"


def _poses(track, n: int, rng: np.random.Generator) -> list[Pose]:
    ref = track.reference
    s = np.concatenate([np.linspace(-20.0, ref.length + 20.0, n), rng.uniform(0.0, ref.length, n)])
    t = np.concatenate([rng.normal(0.0, 2.0, n), rng.uniform(-12.0, 12.0, n)])
    dyaw = np.concatenate([rng.normal(0.0, 0.05, n), rng.uniform(-1.8, 1.8, n)])
    poses = []
    for si, ti, di in zip(s, t, dyaw, strict=True):
        x, y, h = ref.frame(float(si))
        poses.append(Pose(x - ti * np.sin(h), y + ti * np.cos(h), h + di))
    return poses


def _as_tuple(truth: labels.LineTruth) -> tuple:
    return (truth.coeffs.tobytes(), truth.exists, truth.kind, truth.visible, truth.x_far,
            truth.offsets_at(np.arange(0.0, 45.0, 2.5)).tobytes())


@compiled
@pytest.mark.parametrize("spec", [*PRESETS, "urban-curvy@101", "highway@7"])
def test_compiled_lines_are_the_python_lines_to_the_bit(spec, monkeypatch):
    track = load_track(spec)
    poses = _poses(track, 300, np.random.default_rng(3))
    compiled_answers, kinds = [], set()
    for pose in poses:
        s0, _ = track.reference.project(pose.x, pose.y)
        for b in range(len(track.boundaries)):
            truth = labels._line_truth(track, b, pose, s0)
            compiled_answers.append(_as_tuple(truth))
            kinds.add(truth.kind)
    monkeypatch.setattr(labels, "_KERNELS", None)
    python_answers = []
    for pose in poses:
        s0, _ = track.reference.project(pose.x, pose.y)
        python_answers += [_as_tuple(labels._line_truth(track, b, pose, s0)) for b in range(len(track.boundaries))]
    assert compiled_answers == python_answers
    assert "none" in kinds and len(kinds) >= 2  # unpainted stretches and markings both met


@compiled
def test_ego_lines_compiled_and_python_agree_on_a_town_corner(monkeypatch):
    track = load_track("local")
    poses = _poses(track, 200, np.random.default_rng(11))

    def answers() -> list:
        out = []
        for pose in poses:
            try:
                e = labels.ego_lines(track, pose)
            except OffMapError as exc:
                out.append(str(exc))
                continue
            out.append((e.lane, e.width, e.deviation, _as_tuple(e.left), _as_tuple(e.right)))
        return out

    fast = answers()
    monkeypatch.setattr(labels, "_KERNELS", None)
    assert fast == answers()
    assert any(isinstance(a, tuple) and a[3][4] < labels.X_MAX for a in fast)  # a fit range shortened at a corner
