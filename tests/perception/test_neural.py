import math
from importlib import resources

import numpy as np
import pytest

from testbed.defense.ld_deviation import LdDeviation
from testbed.perception.dataset import HELD_OUT_SEEDS, Episode, render_episode
from testbed.perception.detection import CameraFrame
from testbed.perception.neural import FIT, X_ANCHORS, NeuralLaneDetector


@pytest.fixture(scope="module")
def detector() -> NeuralLaneDetector:
    return NeuralLaneDetector(threads=1)


def test_shipped_weights_are_small_and_packaged():
    ref = resources.files("testbed.perception") / "weights" / "lanenet.pt"
    assert ref.is_file()
    assert len(ref.read_bytes()) <= 5 * 1024 * 1024


def test_fit_matrix_reproduces_a_cubic():
    coeffs = np.array([1.2, -0.05, 0.004, -2e-5])
    y = np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), coeffs)
    np.testing.assert_allclose(FIT @ y, coeffs, atol=1e-9)


@pytest.mark.parametrize("image", [
    None,
    np.zeros((0, 0, 3), np.uint8),
    np.zeros((160, 320), np.uint8),
    np.zeros((120, 320, 3), np.uint8),
    np.full((160, 320, 3), np.nan, np.float32),
])
def test_bad_frames_give_an_empty_detection(detector, image):
    ld = detector.detect(CameraFrame(3.0, image))
    assert ld.timestamp == 3.0
    assert ld.left is None and ld.right is None and ld.left_prob == 0.0 and ld.right_prob == 0.0


def test_shipped_weights_on_fresh_held_out_frames(detector):
    """A few dozen frames rendered now from held-out seeds: D_LD within a loose bound of the truth."""
    errors, agree, total = [], 0, 0
    episodes = (Episode("urban-straight", HELD_OUT_SEEDS[3], "day"),
                Episode("highway", HELD_OUT_SEEDS[7], "dusk"))
    for ep in episodes:
        for image, label in render_episode(ep, 14):
            ld = detector.detect(CameraFrame(0.0, image))
            d = LdDeviation(0.5).update(ld, label["lane_width"])
            if d is not None:
                errors.append(abs(d - label["deviation"]))
            pairs = ((ld.left_prob, label["left_exists"]), (ld.right_prob, label["right_exists"]))
            for prob, exists in pairs:
                agree += (prob >= 0.5) == exists
                total += 1
    assert len(errors) >= 20
    assert float(np.mean(errors)) < 0.12
    assert agree / total >= 0.9
    assert all(math.isfinite(e) for e in errors)
