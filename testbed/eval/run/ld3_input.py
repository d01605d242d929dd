"""What Alg. 1 reads at one camera frame, as a run.mcap message (`/ld3/input`): the lane detection the defense
was handed (after tracking and any LD-side attacker) and the localization estimate it was paired with (after any
MSF-side attacker). `ld3 replay` runs a defense again over these messages."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose


def _line(coeffs: np.ndarray | None) -> list[float] | None:
    return None if coeffs is None else [float(c) for c in coeffs]


def ld3_input_message(ld: LaneDetection, est: LocalizationEstimate) -> dict[str, Any]:
    """The JSON message of one (detection, estimate) pair."""
    return {
        "t": float(ld.timestamp),
        "detection": {"left": _line(ld.left), "right": _line(ld.right), "left_prob": float(ld.left_prob),
                      "right_prob": float(ld.right_prob), "x_range": [float(v) for v in ld.x_range],
                      "left_var": ld.left_var, "right_var": ld.right_var},
        "msf": {"t": float(est.t), "x": est.pose.x, "y": est.pose.y, "yaw": est.pose.yaw,
                "cov": [float(v) for v in np.asarray(est.cov, float).ravel()]},
    }


def ld3_input_from_message(message: Mapping[str, Any]) -> tuple[LaneDetection, LocalizationEstimate]:
    """The (detection, estimate) pair a message holds."""
    d, m = message["detection"], message["msf"]
    ld = LaneDetection(float(message["t"]), None if d["left"] is None else np.array(d["left"]),
                       None if d["right"] is None else np.array(d["right"]), float(d["left_prob"]),
                       float(d["right_prob"]), (float(d["x_range"][0]), float(d["x_range"][1])), d["left_var"],
                       d["right_var"])
    est = LocalizationEstimate(float(m["t"]), Pose(float(m["x"]), float(m["y"]), float(m["yaw"])),
                               np.array(m["cov"], float).reshape(3, 3))
    return ld, est
