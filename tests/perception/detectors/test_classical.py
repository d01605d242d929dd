import numpy as np
import pytest

from testbed.defense.ld_deviation import LdDeviation
from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.classical import ClassicalLaneDetector, ego_pair
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle


@pytest.fixture(scope="module")
def detector() -> ClassicalLaneDetector:
    return ClassicalLaneDetector(CameraRig(get_vehicle("sedan").camera))


def test_classical_tracks_the_lane_on_day_frames(detector, heldout_frames):
    day = [(img, lb) for img, lb in heldout_frames[:14]]
    errors = []
    for image, label in day:
        d = LdDeviation(0.5).update(detector.detect(CameraFrame(0.0, image)), label["lane_width"])
        if d is not None:
            errors.append(abs(d - label["deviation"]))
    assert len(errors) >= len(day) // 2
    assert float(np.median(errors)) < 0.3


@pytest.mark.parametrize("image", [None, np.zeros((0, 0, 3), np.uint8), np.zeros((160, 320), np.uint8),
                                   np.full((160, 320, 3), np.nan)])
def test_bad_frames_give_an_empty_detection(detector, image):
    ld = detector.detect(CameraFrame(1.0, image))
    assert ld.left is None and ld.right is None and ld.timestamp == 1.0


def test_blank_road_has_no_lines(detector):
    ld = detector.detect(CameraFrame(0.0, np.full((160, 320, 3), 90, np.uint8)))
    assert ld.left is None and ld.right is None


def test_ego_pair_is_the_narrowest_straddling_pair():
    # a curb ridge 0.4 m outside the left line, the right line, and the next lane's line further right
    assert ego_pair(np.array([-7.1, -3.55, 0.06, 0.48])) == (0.06, -3.55)
    # one side missing: the innermost candidate on the other side
    assert ego_pair(np.array([1.9, 2.3])) == (1.9, None)
    assert ego_pair(np.array([])) == (None, None)
