import numpy as np
import pytest

from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.labels import ego_lines
from testbed.perception.detectors.oracle import OracleLaneDetector
from testbed.perception.detectors.registry import make_detector
from tests.perception.conftest import pose_on
from tracks.pose import Pose


def test_oracle_returns_the_map_lines(track):
    pose = pose_on(track, 1, 60.0, 0.3, 0.02)
    ld = OracleLaneDetector(track, np.random.default_rng(0)).detect(CameraFrame(1.5, None, pose))
    truth = ego_lines(track, pose)
    assert ld.timestamp == 1.5
    np.testing.assert_allclose(ld.left, truth.left.coeffs)
    np.testing.assert_allclose(ld.right, truth.right.coeffs)
    assert ld.left_prob == ld.right_prob == 1.0
    assert ld.x_range == (0.0, 40.0)


def test_oracle_missing_line_is_none(track):
    det = OracleLaneDetector(track, np.random.default_rng(0))
    ld = det.detect(CameraFrame(0.0, None, pose_on(track, 0, 110.0)))
    assert ld.right is None and ld.right_prob == 0.0
    assert ld.left is not None


def test_noise_and_dropout_are_seeded(track):
    pose = pose_on(track, 0, 60.0)
    truth = ego_lines(track, pose).left.coeffs[0]
    offsets = [OracleLaneDetector(track, np.random.default_rng(3), noise_std=0.1).detect(
        CameraFrame(0.0, None, pose)).left[0] - truth for _ in range(2)]
    assert offsets[0] == offsets[1] != 0.0
    noisy = OracleLaneDetector(track, np.random.default_rng(1), noise_std=0.1)
    errs = np.array([noisy.detect(CameraFrame(0.0, None, pose)).left[0] - truth for _ in range(400)])
    assert errs.std() == pytest.approx(0.1, rel=0.2)
    dropping = OracleLaneDetector(track, np.random.default_rng(0), dropout=1.0)
    dropped = dropping.detect(CameraFrame(0.0, None, pose))
    assert dropped.left is None and dropped.right is None


def test_oracle_without_pose_or_off_map_is_empty(track):
    det = OracleLaneDetector(track, np.random.default_rng(0))
    assert det.detect(CameraFrame(2.0, None, None)).left is None
    off = det.detect(CameraFrame(2.0, None, Pose(0.0, 60.0, 0.0)))
    assert off.left is None and off.right is None and off.left_prob == 0.0


def test_factory(track):
    assert make_detector("none", track=track, rig=None) is None
    assert isinstance(make_detector("oracle", track=track, rig=None, rng=np.random.default_rng(0)),
                      OracleLaneDetector)
    with pytest.raises(ValueError, match="unknown lane detector"):
        make_detector("lidar", track=track, rig=None)
