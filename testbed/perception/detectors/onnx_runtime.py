"""LaneNet exported to ONNX and run with onnxruntime (the `nn` extra): same preprocessing, decoding and
`LaneDetection` as `NeuralLaneDetector`, only the network runs in an onnxruntime session. The runtime of the
`neural` detector by default; a process exports and loads each network once."""

from __future__ import annotations

import hashlib
import io
import warnings
from pathlib import Path

import numpy as np
import torch

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.detectors.neural import (
    DEFAULT_FIT,
    FRAME_SHAPE,
    INPUT_WIDTH,
    LaneNet,
    NeuralLaneDetector,
    check_fit,
    lines_from_outputs,
    load_model,
    preprocess,
)

OPSET = 17
INSTALL_HINT = ("onnxruntime is not installed: pip install 'ld3-testbed[nn]' (or set detector.runtime = \"torch\" "
                "for the neural detector)")


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
            raise UserError(INSTALL_HINT) from None
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        self.session = ort.InferenceSession(onnx_model, options, providers=["CPUExecutionProvider"])

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cols, exist = self.session.run(None, {"image": x})
        return cols, exist


def model_digest(model: LaneNet) -> str:
    """A digest of the network a LaneNet is: its width, input rows and every tensor of its state."""
    h = hashlib.sha256(f"{model.width} {model.input_rows}".encode())
    for name, tensor in model.state_dict().items():
        h.update(name.encode())
        h.update(tensor.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()


_SESSIONS: dict[tuple[str, int], OnnxLaneNet] = {}
KEPT_SESSIONS = 4


def session_for(model: LaneNet, threads: int = 1) -> OnnxLaneNet:
    """The onnxruntime session of `model`, exported and loaded once per network and thread count in a process (a
    campaign worker's runs share it; the export is the same bytes every time); the oldest of `KEPT_SESSIONS`
    goes first."""
    key = (model_digest(model), threads)
    if key not in _SESSIONS:
        if len(_SESSIONS) >= KEPT_SESSIONS:
            del _SESSIONS[next(iter(_SESSIONS))]
        _SESSIONS[key] = OnnxLaneNet(export_onnx(model), threads)
    return _SESSIONS[key]


class OnnxLaneDetector(LaneDetector):
    """`NeuralLaneDetector` with the network in onnxruntime (one intra-op thread unless told otherwise), its
    anchors fitted with `fit`. Built, it infers one blank frame: what a process's first frame costs once (the fit's
    per-mask matrices, the session's first run, the decoding's first torch calls) is paid then, not by a run's
    first camera tick; the detector keeps nothing from a frame, so its outputs are unchanged."""

    def __init__(self, model: LaneNet | None = None, threads: int = 1, fit: str = DEFAULT_FIT) -> None:
        model = model if model is not None else load_model()
        self.input_rows = model.input_rows
        self.model = session_for(model, threads)
        self.fit = check_fit(fit)
        self.infer(np.zeros((*FRAME_SHAPE, 3), np.uint8))  # a process's first frame pays its one-off costs here

    def infer(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cubics (2, 4) and existence probabilities (2,) for one valid frame."""
        if image.dtype != np.uint8:
            image = np.clip(image, 0, 255).astype(np.uint8)
        cols, exist = self.model(preprocess(image, self.input_rows)[None])
        coeffs, probs = lines_from_outputs(torch.from_numpy(cols), torch.from_numpy(exist), self.fit)
        return coeffs[0], probs[0]

    def detect(self, frame: CameraFrame) -> LaneDetection:
        if not NeuralLaneDetector.valid_image(frame.image):
            return LaneDetection.empty(frame.t)
        return NeuralLaneDetector.detection(frame.t, *self.infer(frame.image))
