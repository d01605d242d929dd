"""The compiled reference-line kernel answers `heading_at`, `curvature_at`, `frame` and `project` to the bit as
the pure-Python methods do, on every preset: along the lanes (the walk from the last answer), at random offsets,
beyond the ends and far off (the coarse search)."""

import copy
import pickle
import shutil

import numpy as np
import pytest

from tracks.compiled import compiled_module
from tracks.presets import PRESETS, load_track
from tracks.recent import RecentAnswers

KERNELS = compiled_module("tracks.reference_kernels")
compiled = pytest.mark.skipif(KERNELS is None, reason="the Cython kernels are not built (no C compiler at install)")


def _pure(line):
    """The same line answering with the pure-Python methods only, from a cold start."""
    pure = copy.copy(line)
    pure._kernel, pure._hint, pure._memo = None, None, RecentAnswers(16)
    return pure


def test_the_kernel_is_built_where_a_c_compiler_is():
    if shutil.which("cc") is not None or shutil.which("gcc") is not None:
        assert KERNELS is not None, "reinstall (pip install -e .) to build the kernels"


@compiled
@pytest.mark.parametrize("spec", [*PRESETS, "urban-curvy@101", "highway@7"])
def test_kernel_answers_as_the_python_reference(spec):
    line = load_track(spec).reference
    pure, rng = _pure(line), np.random.default_rng(5)
    n = 1500
    s = np.concatenate([np.linspace(-30.0, line.length + 30.0, n), rng.uniform(-60.0, line.length + 60.0, n)])
    t = np.concatenate([rng.normal(0.0, 2.5, n), rng.uniform(-45.0, 45.0, n)])
    for si, ti in zip(s, t, strict=True):
        x, y = pure.point(float(np.clip(si, 0.0, line.length)), float(ti))
        assert line.frame(float(si)) == pure.frame(float(si))
        assert line.heading_at(float(si)) == pure.heading_at(float(si))
        assert line.curvature_at(float(si)) == pure.curvature_at(float(si))
        assert line.project(x, y) == pure.project(x, y)
        assert line.project(x, y, 5.0) == pure.project(x, y, 5.0)


@compiled
def test_non_finite_and_far_points_fall_back_to_python():
    line = load_track("highway").reference
    with pytest.raises(ValueError):
        line.project(float("nan"), 0.0)
    assert line.project(2e9, 0.0) == _pure(line).project(2e9, 0.0)


@compiled
def test_a_line_with_its_kernel_pickles():
    line = load_track("urban-curvy").reference
    copied = pickle.loads(pickle.dumps(line))
    assert copied.project(120.0, 3.0) == line.project(120.0, 3.0)
