"""The lane-detector registry: built-in detectors and the `ld3.detectors` entry points.

A detector component's factory is `factory(track, rig, rng)` (the run's track, camera rig and detector
random stream), returning a `LaneDetector` (or None for `none`). What it `provides` says whether lane
detections reach the defense and whether it reads rendered camera frames (then the run renders them).
"""

from __future__ import annotations

import numpy as np

from testbed.lane_detection import LaneDetector
from testbed.registry import Capability, Component, Registry

_LD = frozenset({Capability.LANE_DETECTOR})
_CAMERA = frozenset({Capability.LANE_DETECTOR, Capability.CAMERA_IMAGE})


def _neural(track, rig, rng: np.random.Generator) -> LaneDetector:
    from testbed.perception.neural import NeuralLaneDetector

    return NeuralLaneDetector()


def _neural_onnx(track, rig, rng: np.random.Generator) -> LaneDetector:
    from testbed.perception.onnx_runtime import OnnxLaneDetector

    return OnnxLaneDetector()


def _classical(track, rig, rng: np.random.Generator) -> LaneDetector:
    from testbed.perception.classical import ClassicalLaneDetector

    return ClassicalLaneDetector(rig)


def _oracle(track, rig, rng: np.random.Generator) -> LaneDetector:
    from testbed.perception.oracle import OracleLaneDetector

    return OracleLaneDetector(track, rng)


DETECTORS: Registry[Component] = Registry("lane detector", Component, "ld3.detectors")
DETECTORS.add(Component("neural", _neural, "LaneNet CNN on the rendered camera, shipped weights", provides=_CAMERA))
DETECTORS.add(Component("neural-onnx", _neural_onnx, "LaneNet exported to ONNX, run with onnxruntime (the onnx extra)",
                        provides=_CAMERA))
DETECTORS.add(Component("classical", _classical, "inverse perspective mapping and a sliding-window fit on the camera",
                        provides=_CAMERA))
DETECTORS.add(Component("oracle", _oracle, "the map's ego lines through the true pose (no camera)", provides=_LD))
DETECTORS.add(Component("none", lambda track, rig, rng: None, "no lane detector"))


def make_detector(name: str, *, track, rig, rng: np.random.Generator | None = None) -> LaneDetector | None:
    """The detector of the registered component `name` (None for `none`; UnknownComponent if unknown)."""
    return DETECTORS.get(name).factory(track, rig, rng if rng is not None else np.random.default_rng(0))
