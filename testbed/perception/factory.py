"""Builds the lane detector a scenario names: 'neural', 'classical', 'oracle' or 'none'."""

from __future__ import annotations

import numpy as np

from testbed.perception.detection import LaneDetector

DETECTORS = ("neural", "classical", "oracle", "none")


def make_detector(name: str, *, track, rig, lane: int | None = None,
                  rng: np.random.Generator | None = None) -> LaneDetector | None:
    """The detector called `name` (None for 'none'); `lane` is accepted for symmetry (the ego lane is the
    one the vehicle is in). Raises ValueError for an unknown name."""
    if name == "none":
        return None
    if name == "oracle":
        from testbed.perception.oracle import OracleLaneDetector

        return OracleLaneDetector(track, rng if rng is not None else np.random.default_rng(0))
    if name == "neural":
        from testbed.perception.neural import NeuralLaneDetector

        return NeuralLaneDetector()
    if name == "classical":
        from testbed.perception.classical import ClassicalLaneDetector

        return ClassicalLaneDetector(rig)
    raise ValueError(f"unknown lane detector {name!r}; choose one of {', '.join(DETECTORS)}")
