"""A lane detector of your own: the map oracle with 5 cm of offset noise and 20 % dropped lines, fed to LD3.

Run: python docs/examples/custom_detector.py
"""

import numpy as np

from testbed import api
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.detectors.oracle import OracleLaneDetector
from tracks.presets import load_track


class FlakyDetector(LaneDetector):
    """Wraps any detector: drops each line with probability `dropout`, adds N(0, std²) to its offset."""

    name = "flaky-oracle"
    reads_camera = False  # no camera frames needed: the run does not render

    def __init__(self, inner: LaneDetector, std: float, dropout: float, seed: int) -> None:
        self.inner, self.std, self.dropout = inner, std, dropout
        self.rng = np.random.default_rng(seed)

    def _flaky(self, coeffs):
        if coeffs is None or self.rng.random() < self.dropout:
            return None
        out = coeffs.copy()
        out[0] += self.rng.normal(0.0, self.std)
        return out

    def detect(self, frame: CameraFrame) -> LaneDetection:
        ld = self.inner.detect(frame)
        left, right = self._flaky(ld.left), self._flaky(ld.right)
        return LaneDetection(ld.timestamp, left, right, ld.left_prob if left is not None else 0.0,
                             ld.right_prob if right is not None else 0.0, ld.x_range)


sc = api.scenario("local", duration=20.0, localization="msf", defense="ld3")
detector = FlakyDetector(OracleLaneDetector(load_track(sc.track), np.random.default_rng(0)), 0.05, 0.2, seed=1)
result = api.run(sc, detector=detector)
fresh = result.frame[result.frame["ld_fresh"] == 1]
error = (fresh["ld_dev"] - fresh["phys_dev"]).abs()
print(f"{result.summary['detector']}: {len(fresh)} detections, |D_LD error| mean {error.mean():.3f} m, "
      f"false alarm: {result.summary['detected']}")
