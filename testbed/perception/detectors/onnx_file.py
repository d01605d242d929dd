"""The lane detector of a vehicle without torch or OpenCV: a detector graph exported by
`testbed.perception.training.onnx_detector_graph` (`ld3 ld export-onnx --out lanenet.onnx`) run with onnxruntime.
A line under 0.5 existence probability is None, as in `NeuralLaneDetector`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector

FRAME_SHAPE = (160, 320, 3)
FRAME_INPUT = "frame"
METADATA_X_MAX = "ld3.x_max"
GRAPH_FITS = ("cubic", "near")  # the anchor fits a detector graph can hold (`neural.MATRIX_FITS`)
METADATA_FIT = "ld3.fit"  # the anchor fit baked into the graph; graphs exported before it was recorded: cubic


class OnnxFileLaneDetector(LaneDetector):
    """Runs the detector graph at `path` in an onnxruntime session (one intra-op thread unless told otherwise); a
    `fit` asked for that is not the one the graph was exported with is a UserError."""

    name = "neural-onnx"

    def __init__(self, path: str | Path, threads: int = 1, fit: str | None = None) -> None:
        try:
            import onnxruntime as ort
        except ImportError:
            raise UserError("an ONNX lane detector needs onnxruntime: pip install 'ld3-testbed[onnx]'") from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own error types for a missing, empty or garbled file
            problem = " ".join(str(exc).split())[:200]
            raise UserError(f"cannot load ONNX detector graph {path}: {problem}") from None
        inputs = [i.name for i in self.session.get_inputs()]
        meta = self.session.get_modelmeta().custom_metadata_map
        if inputs != [FRAME_INPUT] or METADATA_X_MAX not in meta:
            raise UserError(f"{path} is not a detector graph (input {inputs}): export one with "
                            f"`ld3 ld export-onnx --out {Path(path).name}`")
        self.x_max = float(meta[METADATA_X_MAX])
        self.fit = meta.get(METADATA_FIT, "cubic")
        if fit is not None and fit != self.fit:
            remedy = (f"export it again with `ld3 ld export-onnx --fit {fit}`" if fit in GRAPH_FITS else
                      f"the {fit} fit is solved per frame outside any graph: set detector.weights to the checkpoint "
                      f"(.pt)")
            raise UserError(f"{path} was exported with the {self.fit} fit, not {fit}: {remedy} or drop detector.fit")

    def detect(self, frame: CameraFrame) -> LaneDetection:
        image = frame.image
        if not isinstance(image, np.ndarray) or image.shape != FRAME_SHAPE:
            return LaneDetection.empty(frame.t)
        if image.dtype != np.uint8:
            if not np.isfinite(image).all():
                return LaneDetection.empty(frame.t)
            image = np.clip(image, 0, 255).astype(np.uint8)
        coeffs, probs = self.session.run(None, {FRAME_INPUT: np.ascontiguousarray(image)})
        coeffs, probs = coeffs[0], probs[0]
        left, right = (coeffs[i] if probs[i] >= 0.5 else None for i in range(2))
        return LaneDetection(frame.t, left, right, float(probs[0]), float(probs[1]), (0.0, self.x_max))
