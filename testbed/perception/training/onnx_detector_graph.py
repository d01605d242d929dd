"""LaneNet as one self-contained ONNX graph (needs torch to export): the RGB frame (160, 320, 3) uint8 in, the two
ego lines' cubics (2, 4) and existence probabilities (2,) out. The crop, the 2:1 box downsampling (what
OpenCV's INTER_AREA does at an integer ratio), the per-channel standardisation, the network, the column
decoding and the anchor fit (one fit's matrices, gathered by presence mask) all run inside the graph, so
`testbed.perception.detectors.onnx_file.OnnxFileLaneDetector` needs onnxruntime only: no torch, no OpenCV."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import onnx
import torch
from torch import nn
from torch.nn import functional as F

from testbed.errors import UserError
from testbed.perception.detectors.neural import (
    _MASK_BITS,
    CROP_TOP,
    DEFAULT_FIT,
    FRAME_SHAPE,
    GEOMETRY,
    MATRIX_FITS,
    MIN_PRESENT_ANCHORS,
    X_ANCHORS,
    LaneNet,
    _fit_matrices,
    _moments,
    check_fit,
)
from testbed.perception.detectors.onnx_file import FRAME_INPUT, METADATA_FIT, METADATA_X_MAX
from testbed.perception.detectors.onnx_runtime import OPSET


class DetectorGraph(nn.Module):
    """Frame -> (cubics (1, 2, 4) float64, existence probabilities (1, 2) float64), as `NeuralLaneDetector.infer`
    with the anchor fit `fit`."""

    def __init__(self, model: LaneNet, fit: str = DEFAULT_FIT) -> None:
        super().__init__()
        self.model = model.eval()
        self.pool = ((FRAME_SHAPE[0] - CROP_TOP) // model.input_rows, 2)
        self.register_buffer("moments", _moments(torch.float32))
        self.register_buffer("scale", torch.tensor(GEOMETRY.scale, dtype=torch.float32))
        self.register_buffer("fit", torch.from_numpy(_fit_matrices(check_fit(fit))))
        self.register_buffer("bits", torch.from_numpy(_MASK_BITS))
        self.cx = float(GEOMETRY.cx)

    def forward(self, frame: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = frame[CROP_TOP:].permute(2, 0, 1).unsqueeze(0).float()
        x = torch.floor(F.avg_pool2d(x, self.pool) + 0.5)  # as OpenCV: a uint8 result, halves rounded up
        mean = x.mean(dim=(2, 3), keepdim=True)
        std = ((x - mean) ** 2).mean(dim=(2, 3), keepdim=True).sqrt()
        cols, exist = self.model((x - mean) / (std + 4.0))
        moments = torch.softmax(cols, dim=-1) @ self.moments
        mass = moments[..., 1]
        y = (moments[..., 0] / mass.clamp(min=1e-6) - self.cx) * self.scale
        present = mass > 0.5
        matrices = self.fit[(present.long() * self.bits).sum(-1)]
        coeffs = (matrices @ y.double().unsqueeze(-1)).squeeze(-1)
        enough = (present.long().sum(-1) >= MIN_PRESENT_ANCHORS).double()
        return coeffs, torch.sigmoid(exist.double()) * enough


def export_detector_onnx(model: LaneNet, path: str | Path | None = None, fit: str = DEFAULT_FIT) -> bytes:
    """The detector graph of the eval-mode `model` with the anchor fit `fit` (the valid x range's end and the fit in
    its metadata); also written to `path` when given. The `spread` fit, solved per frame, is refused in one line."""
    if check_fit(fit) not in MATRIX_FITS:
        raise UserError(f"the {fit} fit is solved per frame and cannot be baked into a detector graph: export with "
                        f"--fit {' or '.join(MATRIX_FITS)}, or run detector neural-onnx on the checkpoint (.pt), whose "
                        f"fit runs outside the network's graph")
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation and tracer notes
        torch.onnx.export(DetectorGraph(model, fit), (torch.zeros(*FRAME_SHAPE, 3, dtype=torch.uint8),), buf,
                          input_names=[FRAME_INPUT], output_names=["cubics", "existence"], opset_version=OPSET,
                          dynamo=False)
    graph = onnx.load_from_string(buf.getvalue())
    onnx.helper.set_model_props(graph, {METADATA_X_MAX: repr(X_ANCHORS[-1]), METADATA_FIT: fit})
    data = graph.SerializeToString()
    if path is not None:
        Path(path).write_bytes(data)
    return data
