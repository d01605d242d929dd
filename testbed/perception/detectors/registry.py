"""The lane-detector registry: built-in detectors and the `ld3.detectors` entry points.

A detector component's factory is `factory(track, rig, rng, **params)` (the run's track, camera rig and
detector random stream, and the `[detector]` parameters its `params` model validated, less `tracking` and
`track_at`, which the loop acts on), returning a `LaneDetector` (or None for `none`). What it `provides` says whether
lane detections reach the defense and whether it reads rendered camera frames (then the run renders them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator

from testbed.lane_detection import LaneDetector
from testbed.lane_tracker import TrackerParams
from testbed.params import Params
from testbed.perception.detectors.weights import SHIPPED, resolve
from testbed.registry import Capability, Component, Registry

_LD = frozenset({Capability.LANE_DETECTOR})
_CAMERA = frozenset({Capability.LANE_DETECTOR, Capability.CAMERA_IMAGE})


class CameraDetectorParams(Params):
    """Parameters of every detector that reads the camera: whether the loop tracks its lines."""

    tracking: bool = Field(True, description="track the detected lines over frames with the chassis odometry "
                                             "(testbed.lane_tracker), between the detector and LD3")
    track_at: list[float] = Field(default_factory=lambda: list(TrackerParams().measure_at),
                                  description="distances ahead (m, increasing, at least two; 0 is the car) where the "
                                  "tracker measures each detected line, its cubic's value there; [] measures the "
                                  "cubic's coefficients instead (whose offset and slope at the car are the fit's "
                                  "extrapolation: more benign alarms on real maps' corners; "
                                  "docs/lane-tracking-security.md)")

    @field_validator("track_at")
    @classmethod
    def _ahead(cls, value: list[float]) -> list[float]:
        TrackerParams(measure_at=tuple(value))  # its ValueError names what is wrong
        return value


class NeuralParams(CameraDetectorParams):
    """Parameters of the neural detectors (torch and onnxruntime)."""

    weights: str | None = Field(None, description="checkpoint path, or the shipped checkpoint by name: lanenet.pt (the "
                                                  "default, with and without traffic); for neural-onnx also a "
                                                  "detector graph (.onnx) from `ld3 ld export-onnx`")
    fit: Literal["cubic", "near", "spread"] | None = Field(
        None, description="the fit of the network's anchors into each line's cubic: cubic (fixed anchor weights, a "
                          "prior on c3), near (anchors weighted by the inverse square of their measured error, "
                          "which grows with distance: misread far anchors move the offset and slope at the car "
                          "less) or spread (each frame's anchors weighted by the network's own spread of its "
                          "column scores there, near's error as the floor; not in a detector graph (.onnx)); "
                          "unset: cubic, and for a detector graph the fit it was exported with")

    @field_validator("weights")
    @classmethod
    def _exists(cls, value: str | None) -> str | None:
        if value is not None and not resolve(value).is_file():
            raise ValueError(f"no checkpoint at {value}: name a shipped one ({', '.join(SHIPPED)}), train one with "
                             f"`ld3 ld train` or drop detector.weights")
        return value


class NeuralRuntimeParams(NeuralParams):
    """Parameters of the neural detector: its weights and the runtime its network runs in."""

    runtime: Literal["onnxruntime", "torch"] = Field(
        "onnxruntime", description="where LaneNet runs: onnxruntime (the network exported from the checkpoint; half "
                                   "torch's time a frame) or torch (its cubics and probabilities differ from "
                                   "onnxruntime's by up to about 2e-5)")


class OracleParams(Params):
    """Parameters of the oracle detector."""

    noise_std: float = Field(0.0, ge=0.0, description="std of the noise added to each line's offset c0 (m)")
    dropout: float = Field(0.0, ge=0.0, le=1.0, description="probability that a present line is dropped")


def _neural(track, rig, rng: np.random.Generator, weights: str | None = None,
            runtime: str = "onnxruntime", fit: str = "cubic") -> LaneDetector:
    from testbed.perception.detectors.neural import NeuralLaneDetector, load_model

    model = load_model(resolve(weights) if weights is not None else None)
    if runtime == "torch":
        return NeuralLaneDetector(model, fit=fit)
    from testbed.perception.detectors.onnx_runtime import OnnxLaneDetector

    return OnnxLaneDetector(model, fit=fit)


def _neural_onnx(track, rig, rng: np.random.Generator, weights: str | None = None,
                 fit: str | None = None) -> LaneDetector:
    if weights is not None and weights.endswith(".onnx"):  # an exported detector graph: no torch needed
        from testbed.perception.detectors.onnx_file import OnnxFileLaneDetector

        return OnnxFileLaneDetector(Path(weights).expanduser(), fit=fit)
    return _neural(track, rig, rng, weights, runtime="onnxruntime", fit=fit or "cubic")


def _classical(track, rig, rng: np.random.Generator) -> LaneDetector:
    from testbed.perception.detectors.classical import ClassicalLaneDetector

    return ClassicalLaneDetector(rig)


def _oracle(track, rig, rng: np.random.Generator, noise_std: float = 0.0, dropout: float = 0.0) -> LaneDetector:
    from testbed.perception.detectors.oracle import OracleLaneDetector

    return OracleLaneDetector(track, rng, noise_std, dropout)


DETECTORS: Registry[Component] = Registry("lane detector", Component, "ld3.detectors")
DETECTORS.add(Component("neural", _neural, "LaneNet CNN on the rendered camera, shipped weights (onnxruntime)",
                        provides=_CAMERA, params=NeuralRuntimeParams))
DETECTORS.add(Component("neural-onnx", _neural_onnx, "LaneNet exported to ONNX, run with onnxruntime (the onnx extra)",
                        provides=_CAMERA, params=NeuralParams))
DETECTORS.add(Component("classical", _classical, "inverse perspective mapping and a sliding-window fit on the camera",
                        provides=_CAMERA, params=CameraDetectorParams))
DETECTORS.add(Component("oracle", _oracle, "the map's ego lines through the true pose (no camera)", provides=_LD,
                        params=OracleParams))
DETECTORS.add(Component("none", lambda track, rig, rng: None, "no lane detector"))


def make_detector(name: str, *, track, rig, rng: np.random.Generator | None = None,
                  params: dict[str, Any] | None = None) -> LaneDetector | None:
    """The detector of the registered component `name` with its `[detector]` parameters (None for `none`;
    UnknownComponent if unknown, ParamsError for bad parameters)."""
    component = DETECTORS.get(name)
    settings = component.settings(params or {}, f"detector {name}").model_dump(exclude_unset=True,
                                                                              exclude={"tracking", "track_at"})
    return component.factory(track, rig, rng if rng is not None else np.random.default_rng(0), **settings)

