"""LaneNet exported to ONNX and run with onnxruntime (the `onnx` extra): same preprocessing, decoding and
`LaneDetection` as `NeuralLaneDetector`, only the network runs in an onnxruntime session."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
import torch

from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.detectors.neural import (
    INPUT_WIDTH,
    LaneNet,
    NeuralLaneDetector,
    lines_from_outputs,
    load_model,
    preprocess,
)

OPSET = 17
INSTALL_HINT = "onnxruntime is not installed: pip install 'ld3-testbed[onnx]' (or use detector neural)"


def export_onnx(model: LaneNet, path: str | Path | None = None) -> bytes:
    """The eval-mode model as an ONNX graph for one frame (input `image` (1, 3, input rows, 160), outputs
    `columns`, `existence`); also written to `path` when given."""
    model = model.eval()
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation and tracer notes
        torch.onnx.export(model, (torch.zeros(1, 3, model.input_rows, INPUT_WIDTH),), buf, input_names=["image"],
                          output_names=["columns", "existence"],
                          opset_version=OPSET, dynamo=False)
    data = buf.getvalue()
    if path is not None:
        Path(path).write_bytes(data)
    return data


class OnnxLaneNet:
    """An onnxruntime session of an exported LaneNet: (1, 3, input rows, 160) float32 -> (column logits,
    existence logits) as numpy arrays."""

    def __init__(self, onnx_model: bytes, threads: int = 1) -> None:
        try:
            import onnxruntime as ort
        except ImportError:
            raise RuntimeError(INSTALL_HINT) from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        self.session = ort.InferenceSession(onnx_model, options, providers=["CPUExecutionProvider"])

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cols, exist = self.session.run(None, {"image": x})
        return cols, exist


class OnnxLaneDetector(LaneDetector):
    """`NeuralLaneDetector` with the network in onnxruntime (one intra-op thread unless told otherwise)."""

    def __init__(self, model: LaneNet | None = None, threads: int = 1) -> None:
        model = model if model is not None else load_model()
        self.input_rows = model.input_rows
        self.model = OnnxLaneNet(export_onnx(model), threads)

    def infer(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cubics (2, 4) and existence probabilities (2,) for one valid frame."""
        if image.dtype != np.uint8:
            image = np.clip(image, 0, 255).astype(np.uint8)
        cols, exist = self.model(preprocess(image, self.input_rows)[None])
        coeffs, probs = lines_from_outputs(torch.from_numpy(cols), torch.from_numpy(exist))
        return coeffs[0], probs[0]

    def detect(self, frame: CameraFrame) -> LaneDetection:
        if not NeuralLaneDetector.valid_image(frame.image):
            return LaneDetection.empty(frame.t)
        return NeuralLaneDetector.detection(frame.t, *self.infer(frame.image))
