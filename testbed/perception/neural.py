"""Neural lane detector: a small CNN regressing the ego lines at fixed ground distances, decoded to cubics.

Model (`LaneNet`): the ground part of the frame (rows below the top 30 %, horizon included) is area-
resized to 56×160, standardised per channel (exposure invariance) and passed through five strided
conv-BN-ReLU blocks and a two-layer head. The head outputs, for the left and the right line, the lateral
offset y (m, vehicle frame) at the anchor distances `X_ANCHORS` (x = 0 included: the network learns the
extrapolation to the reference point, which is what Alg. 3 reads) and an existence logit. A weighted
least-squares cubic through the anchors gives the `LaneDetection` coefficients.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import cv2
import numpy as np
import torch
from torch import nn

from testbed.perception.detection import CameraFrame, LaneDetection, LaneDetector

X_ANCHORS = (0.0, 4.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0, 35.0, 40.0)
ANCHOR_WEIGHTS = (8.0, 4.0, 2.0, 1.5, 1.0, 1.0, 0.7, 0.5, 0.4, 0.3)  # fit and loss emphasis near x = 0
Y_SCALE = 4.0  # m: targets are y / Y_SCALE
FRAME_SHAPE = (160, 320)  # rendered frame (H, W) the model is trained on
CROP_TOP = 48  # rows above are sky
INPUT_SHAPE = (56, 160)  # network input (H, W)
DEFAULT_WEIGHTS = "lanenet.pt"


def _block(c_in: int, c_out: int, stride: int) -> nn.Sequential:
    conv = nn.Conv2d(c_in, c_out, 3, stride, 1, bias=False)
    return nn.Sequential(conv, nn.BatchNorm2d(c_out), nn.ReLU(inplace=True))


class LaneNet(nn.Module):
    """CNN: (N, 3, 56, 160) standardised image -> (N, 2K + 2): left, right y/Y_SCALE at anchors, 2 logits."""

    def __init__(self, widths: tuple[int, ...] = (16, 24, 32, 48, 64), hidden: int = 128) -> None:
        super().__init__()
        strides = (2, 2, 2, 1, 2)
        layers, c_in = [], 3
        for c_out, s in zip(widths, strides, strict=True):
            layers.append(_block(c_in, c_out, s))
            c_in = c_out
        self.features = nn.Sequential(*layers)
        h, w = INPUT_SHAPE
        for s in strides:
            h, w = (h + 1) // s if s > 1 else h, (w + 1) // s if s > 1 else w
        self.head = nn.Sequential(
            nn.Flatten(), nn.Linear(c_in * h * w, hidden), nn.ReLU(inplace=True),
            nn.Linear(hidden, 2 * len(X_ANCHORS) + 2),
        )
        self.widths, self.hidden = widths, hidden

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))


def preprocess(image: np.ndarray) -> np.ndarray:
    """Frame (160, 320, 3) uint8 -> network input (3, 56, 160) float32, standardised per channel."""
    crop = cv2.resize(image[CROP_TOP:], (INPUT_SHAPE[1], INPUT_SHAPE[0]), interpolation=cv2.INTER_AREA)
    x = crop.astype(np.float32)
    x -= x.mean(axis=(0, 1))
    x /= x.std(axis=(0, 1)) + 4.0
    return np.ascontiguousarray(x.transpose(2, 0, 1))


def _fit_matrix() -> np.ndarray:
    """(4, K) matrix mapping anchor offsets to weighted least-squares cubic coefficients (ascending)."""
    x = np.asarray(X_ANCHORS)
    w = np.sqrt(np.asarray(ANCHOR_WEIGHTS))
    vander = np.vander(x, 4, increasing=True)
    return np.linalg.pinv(vander * w[:, None]) * w[None, :]


FIT = _fit_matrix()


@dataclass(frozen=True)
class DecodedLines:
    """Network output in metres: anchor offsets (2, K) for left and right and existence probabilities (2,)."""

    anchors_y: np.ndarray
    probs: np.ndarray


def decode(output: np.ndarray) -> DecodedLines:
    k = len(X_ANCHORS)
    y = output[: 2 * k].reshape(2, k) * Y_SCALE
    probs = 1.0 / (1.0 + np.exp(-output[2 * k :]))
    return DecodedLines(y, probs)


def load_model(path: str | Path | None = None) -> LaneNet:
    """LaneNet from a checkpoint (default: the shipped weights inside the package), in eval mode."""
    if path is None:
        ref = resources.files("testbed.perception") / "weights" / DEFAULT_WEIGHTS
        with resources.as_file(ref) as p:
            ckpt = torch.load(p, map_location="cpu", weights_only=True)
    else:
        ckpt = torch.load(Path(path), map_location="cpu", weights_only=True)
    model = LaneNet(tuple(ckpt["widths"]), int(ckpt["hidden"]))
    model.load_state_dict(ckpt["state_dict"])
    return model.eval()


class NeuralLaneDetector(LaneDetector):
    """Runs LaneNet on a frame; lines whose existence probability is under 0.5 are reported as None."""

    def __init__(self, model: LaneNet | None = None, threads: int | None = None) -> None:
        if threads is not None:
            torch.set_num_threads(threads)
        self.model = model if model is not None else load_model()
        self.last_latency_s = 0.0

    @staticmethod
    def valid_image(image: np.ndarray | None) -> bool:
        return (
            isinstance(image, np.ndarray)
            and image.shape == (*FRAME_SHAPE, 3)
            and (image.dtype == np.uint8 or bool(np.isfinite(image).all()))
        )

    def predict(self, image: np.ndarray) -> DecodedLines:
        """Raw decoded network output for one valid frame."""
        x = torch.from_numpy(preprocess(np.asarray(image, dtype=np.uint8)))[None]
        with torch.inference_mode():
            out = self.model(x)[0].numpy().astype(np.float64)
        return decode(out)

    def detect(self, frame: CameraFrame) -> LaneDetection:
        start = time.perf_counter()
        if not self.valid_image(frame.image):
            return LaneDetection.empty(frame.t)
        dec = self.predict(frame.image)
        lines = []
        for i in range(2):
            coeffs = FIT @ dec.anchors_y[i]
            lines.append(coeffs if dec.probs[i] >= 0.5 else None)
        self.last_latency_s = time.perf_counter() - start
        return LaneDetection(frame.t, lines[0], lines[1], float(dec.probs[0]), float(dec.probs[1]),
                             (X_ANCHORS[0], X_ANCHORS[-1]))
