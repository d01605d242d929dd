"""Neural lane detector: row-anchor column classification (Ultra-Fast-Lane-Detection style) on the camera frame.

Anchors are the image rows that see fixed ground distances `X_ANCHORS` ahead (nominal rig). The ground part
of the frame is area-resized to 56×160 (or 112×160, `INPUT_ROWS`) and standardised per channel (exposure
invariance); a fully convolutional backbone keeps 40 columns (8 px each) and widens its lateral view with 1×9
convs. For each line (left, right) and anchor the head scores the 40 columns plus an "absent" class; the softmax
expectation over the columns gives a sub-cell column u, which the nominal flat-ground homography maps to y (m)
at that anchor's distance. A weighted least-squares polynomial through the present anchors is the `LaneDetection`
cubic (degree 3 from `CUBIC_MIN_ANCHORS` present anchors, 2 from `QUADRATIC_MIN_ANCHORS`, else 1), with a
zero-mean Gaussian prior on c3 from road geometry (`CUBIC_PRIOR_STD`; arcs, c3 = 0, stay unbiased) that keeps
a few bad anchors from bending the line; c0 is its extrapolation to the reference point. The fit is one of
`FITS`: `cubic` weighs the anchors by `ANCHOR_WEIGHTS` (10:1 from the nearest to the farthest); `near` by the
inverse square of each anchor's measured error (`ANCHOR_ERROR_M`, 40:1), so that misread far anchors move c0 and
c1 less; `spread` per frame by the inverse of the column distribution's variance at each anchor plus that error
squared (the network's own uncertainty: wide where it misreads; solved per frame, no per-mask matrix); all return
arcs exactly. A pooled branch
gives the existence logit of each line. Inference runs `FrozenLaneNet`: BatchNorm folded into the
convolutions, the forward pass as plain functional calls.
"""

from __future__ import annotations

import copy
import functools
import pickle
from collections.abc import Callable
from importlib import resources
from pathlib import Path

import cv2
import numpy as np
import torch
from scipy.special import expit
from torch import nn
from torch.nn import functional as F
from torch.nn.utils.fusion import fuse_conv_bn_eval

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.perception.detectors.anchors import ANCHOR_WEIGHTS, X_ANCHORS
from vehicles.camera_rig import CameraRig
from vehicles.params import CameraParams

FIT_SCALE = 30.0  # m: the fit runs in t = x / FIT_SCALE, which keeps its normal equations well conditioned
RIDGE = 1e-9  # t-basis ridge on every coefficient: numerical safety only (no visible bias; fit in float64)
PINNED = 1e3  # t-basis ridge that holds a coefficient at 0 when too few anchors are present to fit it
ANCHOR_NOISE_M = 0.05  # anchor offset noise (m) at unit anchor weight: scales the prior against the data
CUBIC_PRIOR_STD = 1e-4  # prior std of c3 (1/m²): c3 = κ'/6, clothoid transitions reach κ' ≈ 6e-4 1/m²
CUBIC_MIN_ANCHORS, QUADRATIC_MIN_ANCHORS = 5, 4
# mean |decoded - label| offset (m) per anchor, both shipped checkpoints on 1800 training frames (presets, with and
# without traffic): the `near` fit's anchor noise
ANCHOR_ERROR_M = (0.042, 0.048, 0.055, 0.061, 0.071, 0.086, 0.102, 0.124, 0.145, 0.206, 0.266)
FITS = ("cubic", "near", "spread")
MATRIX_FITS = ("cubic", "near")  # fits linear in the anchors: one matrix per presence mask, exportable into a graph
DEFAULT_FIT = "cubic"
FRAME_SHAPE = (160, 320)  # rendered frame (H, W) the model is trained on
CROP_TOP = 48  # rows above are sky
INPUT_WIDTH = 160  # network input columns: the frame's halved
MAX_WIDTH = 512  # channels: a checkpoint cannot make the loader build a larger network
INPUT_ROWS = (56, 112)  # network input rows a LaneNet can be built for: the ground crop's halved, or all kept
N_COLS = 40  # column cells; cell j covers full-resolution columns [8j, 8j + 8)
DEFAULT_WEIGHTS = "lanenet.pt"


def _block(c_in: int, c_out: int, stride: tuple[int, int] = (1, 1),
           kernel: tuple[int, int] = (3, 3)) -> nn.Sequential:
    conv = nn.Conv2d(c_in, c_out, kernel, stride, (kernel[0] // 2, kernel[1] // 2), bias=False)
    return nn.Sequential(conv, nn.BatchNorm2d(c_out), nn.ReLU(inplace=True))


class LaneNet(nn.Module):
    """(N, 3, R, 160) image, R = `input_rows` -> column logits (N, 2, K, N_COLS + 1) (last: absent), existence
    logits (N, 2). With 112 rows the fourth block halves the rows too, so both inputs reach the 7 × 40 feature
    map the heads read."""

    def __init__(self, width: int = 32, input_rows: int = INPUT_ROWS[0]) -> None:
        super().__init__()
        if input_rows not in INPUT_ROWS:
            raise ValueError(f"input_rows must be one of {INPUT_ROWS}, got {input_rows}")
        self.width, self.input_rows = width, input_rows
        k = len(X_ANCHORS)
        self.features = nn.Sequential(
            _block(3, 16, (2, 2)), _block(16, 32, (2, 2)), _block(32, width, (2, 1)),
            _block(width, width, (input_rows // INPUT_ROWS[0], 1)), _block(width, width, kernel=(1, 9)),
            _block(width, width, kernel=(1, 9)),
        )
        rows = 7
        self.columns = nn.Conv1d(width * rows + 1, 2 * k, 1)
        self.pool = nn.AdaptiveAvgPool2d((rows, 8))
        self.glob = nn.Sequential(nn.Flatten(), nn.Linear(width * rows * 8, 64), nn.ReLU(inplace=True),
                                  nn.Linear(64, 2 * k + 2))
        self.register_buffer("coord", torch.linspace(-1.0, 1.0, N_COLS)[None, None, :], persistent=False)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return head_outputs(self.features(x), self._columns, lambda f: self.glob(self.pool(f)))

    def _columns(self, flat: torch.Tensor) -> torch.Tensor:
        return self.columns(torch.cat([flat, self.coord.expand(len(flat), 1, N_COLS)], dim=1))


def head_outputs(f: torch.Tensor, columns: Callable[[torch.Tensor], torch.Tensor],
                 pooled: Callable[[torch.Tensor], torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    """Backbone features f (N, C, 7, N_COLS) -> the network's outputs, laid out as `decode` reads them: column
    logits (`columns` maps the flattened rows (N, 7C, N_COLS) to (N, 2K, N_COLS)) with each anchor's "absent"
    logit appended, and the existence logits; `pooled` maps f to the pooled branch's 2K + 2 values."""
    n, k = f.shape[0], len(X_ANCHORS)
    cols = columns(f.flatten(1, 2)).view(n, 2, k, N_COLS)
    g = pooled(f)
    absent = g[:, : 2 * k].view(n, 2, k, 1)
    return torch.cat([cols, absent], dim=-1), g[:, 2 * k :]


def preprocess(image: np.ndarray, rows: int = INPUT_ROWS[0]) -> np.ndarray:
    """Frame (160, 320, 3) uint8 -> network input (3, rows, 160) float32, standardised per channel."""
    crop = cv2.resize(image[CROP_TOP:], (INPUT_WIDTH, rows), interpolation=cv2.INTER_AREA)
    mean, std = cv2.meanStdDev(crop)
    x = np.empty((3, rows, INPUT_WIDTH), np.float32)
    for c, plane in enumerate(cv2.split(crop)):  # planar copy: 2x faster than a transposed astype
        x[c] = plane
    x -= mean.astype(np.float32)[:, :, None]
    x *= (1.0 / (std.astype(np.float32) + 4.0))[:, :, None]
    return x


class AnchorGeometry:
    """Nominal-rig geometry of the anchors: y = scale_k (u - cx) at anchor k; cell centres in pixels."""

    def __init__(self, params: CameraParams | None = None) -> None:
        rig = CameraRig(params if params is not None else CameraParams())
        x = np.asarray(X_ANCHORS)
        uv0 = rig.ground_to_pixel(np.column_stack([x, np.zeros_like(x)]))
        uv1 = rig.ground_to_pixel(np.column_stack([x, np.ones_like(x)]))
        self.cx = float(uv0[0, 0])
        self.rows = uv0[:, 1]
        self.scale = 1.0 / (uv1[:, 0] - uv0[:, 0])  # m per pixel (negative: u grows to the right)
        self.cell_u = 8.0 * np.arange(N_COLS) + 3.5

    def y_to_u(self, y: np.ndarray) -> np.ndarray:
        return y / self.scale + self.cx


GEOMETRY = AnchorGeometry()
_T = torch.tensor(X_ANCHORS, dtype=torch.float64) / FIT_SCALE
_VANDER = torch.stack([_T**p for p in range(4)], dim=-1)  # (K, 4)
_OUTER = _VANDER[:, :, None] * _VANDER[:, None, :]  # (K, 4, 4)
_UNSCALE = torch.tensor([FIT_SCALE**p for p in range(4)], dtype=torch.float64)
_VANDER_NP, _OUTER_NP, _UNSCALE_NP, _EYE4 = _VANDER.numpy(), _OUTER.numpy(), _UNSCALE.numpy(), np.eye(4)
_FLOOR2 = np.asarray(ANCHOR_ERROR_M) ** 2  # the spread fit's floor: each anchor's measured error, squared
_PRIOR3 = RIDGE + (ANCHOR_NOISE_M / (CUBIC_PRIOR_STD * FIT_SCALE**3)) ** 2  # t-basis ridge of the c3 prior
_FIT_W = {"cubic": torch.tensor(ANCHOR_WEIGHTS, dtype=torch.float64),
          "near": (ANCHOR_NOISE_M / torch.tensor(ANCHOR_ERROR_M, dtype=torch.float64)) ** 2}
_M_PER_PX = {dt: torch.tensor(GEOMETRY.scale, dtype=dt) for dt in (torch.float32, torch.float64)}


def _moments(dtype: torch.dtype) -> torch.Tensor:
    """(N_COLS + 1, 2): probabilities @ it = (sum of p·u over the columns, column mass); the absent class adds 0."""
    m = torch.zeros(N_COLS + 1, 2, dtype=dtype)
    m[:N_COLS, 0] = torch.tensor(GEOMETRY.cell_u, dtype=dtype)
    m[:N_COLS, 1] = 1.0
    return m


_MOMENTS = {dt: _moments(dt) for dt in _M_PER_PX}


def check_fit(fit: str) -> str:
    """`fit` if it names one of `FITS`, else a UserError listing them."""
    if fit not in FITS:
        raise UserError(f"unknown lane-line fit {fit!r}: use one of {', '.join(FITS)}")
    return fit


def spread_weights(variance: np.ndarray) -> np.ndarray:
    """The `spread` fit's anchor weights from the column distributions' variances (…, K) in m²: the inverse of
    the variance plus the anchor's measured error squared (`ANCHOR_ERROR_M`, its floor), at the scale of the other
    fits (unit weight for `ANCHOR_NOISE_M`); a zero variance gives the `near` fit's weight."""
    return ANCHOR_NOISE_M**2 / (variance + _FLOOR2)


def fit_cubics(y: torch.Tensor, present: torch.Tensor, fit: str = DEFAULT_FIT,
               variance: torch.Tensor | None = None) -> torch.Tensor:
    """Weighted least-squares cubics (…, 4) through anchor offsets y (…, K) where `present` (…, K), with the
    anchor weights of `fit` (for `spread`, from the anchors' `variance` (…, K), m²), c3 drawn toward 0 by the
    road-geometry prior; with fewer than `CUBIC_MIN_ANCHORS` (`QUADRATIC_MIN_ANCHORS`) present anchors c3 (and
    c2) are held at 0."""
    dt = y.dtype
    if check_fit(fit) == "spread":
        if variance is None:
            raise ValueError("the spread fit weighs the anchors by their variance: pass it")
        w = torch.from_numpy(spread_weights(variance.detach().cpu().double().numpy())).to(y) * present
    else:
        w = _FIT_W[fit].to(dt) * present
    n = present.sum(-1, keepdim=True)
    small = torch.full_like(n, RIDGE)
    ridge = torch.cat([small, small, torch.where(n < QUADRATIC_MIN_ANCHORS, PINNED, RIDGE),
                       torch.where(n < CUBIC_MIN_ANCHORS, PINNED, _PRIOR3)], dim=-1)
    a = torch.einsum("...k,kij->...ij", w, _OUTER.to(dt)) + torch.diag_embed(ridge)
    b = torch.einsum("...k,ki,...k->...i", w, _VANDER.to(dt), y)
    return torch.linalg.solve(a, b.unsqueeze(-1)).squeeze(-1) / _UNSCALE.to(dt)


def decode(cols: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Column logits (…, K, N_COLS + 1) -> anchor offsets y (…, K) in metres and presence probabilities (…, K)."""
    moments = torch.softmax(cols, dim=-1) @ _MOMENTS[cols.dtype]
    mass = moments[..., 1]
    u = moments[..., 0] / mass.clamp(min=1e-6)
    return (u - GEOMETRY.cx) * _M_PER_PX[cols.dtype], mass


def anchor_variance(cols: np.ndarray) -> np.ndarray:
    """Column logits (…, K, N_COLS + 1) -> the variance (…, K, float64) in m² of each anchor's column distribution
    (the absent class left out: the softmax over the columns alone), mapped to metres at the anchor's distance by
    the homography's scale: the network's own uncertainty about the anchor."""
    logits = np.asarray(cols, np.float64)[..., :N_COLS]
    p = np.exp(logits - logits.max(-1, keepdims=True))
    p /= p.sum(-1, keepdims=True)
    du = GEOMETRY.cell_u - (p * GEOMETRY.cell_u).sum(-1, keepdims=True)
    return (p * du**2).sum(-1) * GEOMETRY.scale**2


def spread_cubics(y: np.ndarray, present: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """`fit_cubics` of the `spread` fit in numpy (…, 4) for anchor offsets y, presence (bools) and variances (…, K):
    a frame's two 4×4 solves, without torch's per-call cost on tensors this small."""
    w = spread_weights(variance) * present
    n = present.sum(-1)
    ridge = np.zeros((*n.shape, 4))
    ridge[..., :2] = RIDGE
    ridge[..., 2] = np.where(n < QUADRATIC_MIN_ANCHORS, PINNED, RIDGE)
    ridge[..., 3] = np.where(n < CUBIC_MIN_ANCHORS, PINNED, _PRIOR3)
    a = (w @ _OUTER_NP.reshape(len(X_ANCHORS), 16)).reshape(*n.shape, 4, 4) + ridge[..., None] * _EYE4
    b = (w * y) @ _VANDER_NP
    return np.linalg.solve(a, b[..., None])[..., 0] / _UNSCALE_NP


@functools.cache
def _fit_matrices(fit: str = DEFAULT_FIT) -> np.ndarray:
    """`fit_cubics` as (4, K) matrices for all 2^K presence masks, indexed by the mask's bits (anchor k = bit k);
    only for `MATRIX_FITS`: the spread fit's weights change with every frame."""
    if check_fit(fit) not in MATRIX_FITS:
        raise UserError(f"the {fit} fit weighs each frame's anchors by the network's spread: it has no per-mask "
                        f"matrices (use one of {', '.join(MATRIX_FITS)})")
    k = len(X_ANCHORS)
    masks = (np.arange(2**k)[:, None] >> np.arange(k)) & 1
    eye = torch.eye(k, dtype=torch.float64).expand(2**k, k, k)
    present = torch.from_numpy(masks).double()[:, None, :].expand(2**k, k, k)
    return fit_cubics(eye, present, fit).numpy().transpose(0, 2, 1).copy()


_MASK_BITS = 1 << np.arange(len(X_ANCHORS))
MIN_PRESENT_ANCHORS = 3  # a line decoded at fewer present anchors is not output


def fit_matrices(present: np.ndarray, fit: str = DEFAULT_FIT) -> np.ndarray:
    """`fit_cubics` of `fit` as (…, 4, K) matrices for presence masks (…, K bools): cubic = M @ y. All masks are
    solved once per fit, on first use, so no frame pays for a solve."""
    return _fit_matrices(fit)[present.astype(np.int64) @ _MASK_BITS]


def lines_from_outputs(cols: torch.Tensor, exist: torch.Tensor,
                       fit: str = DEFAULT_FIT) -> tuple[np.ndarray, np.ndarray]:
    """Network outputs for N frames -> cubics (N, 2, 4) of `fit` through the anchors decoded as present (`spread`:
    solved per frame with the columns' variances), and existence probabilities (N, 2), 0 for a line with fewer than
    `MIN_PRESENT_ANCHORS` present anchors."""
    y, present = decode(cols)
    mask = present.numpy() > 0.5
    if fit == "spread":  # solved per frame: its weights are the frame's own
        coeffs = spread_cubics(y.double().numpy(), mask, anchor_variance(cols.numpy()))
    else:
        coeffs = np.einsum("nlck,nlk->nlc", fit_matrices(mask, fit), y.double().numpy())
    probs = expit(exist.double().numpy()) * (mask.sum(-1) >= MIN_PRESENT_ANCHORS)
    return coeffs, probs


class FrozenLaneNet:
    """Inference form of a LaneNet: BatchNorm folded into each convolution, forward run as plain functional
    calls without module dispatch (one thread: 1.20 ms median against 1.50 ms for the folded eager module, measured
    together at stop 10); same outputs as the eval-mode model."""

    def __init__(self, model: LaneNet) -> None:
        model = copy.deepcopy(model).eval()
        with torch.no_grad():
            self.convs = []
            for conv, bn, _ in model.features:
                fused = fuse_conv_bn_eval(conv, bn)
                self.convs.append((fused.weight.detach(), fused.bias.detach(), fused.stride, fused.padding))
        # the 1x1 column conv as a matrix; its weights on the constant coord row fold into a per-column bias
        weight, bias = model.columns.weight.detach()[..., 0], model.columns.bias.detach()
        self.columns = (weight[:, :-1].contiguous(), (weight[:, -1:] * model.coord[0] + bias[:, None]).contiguous())
        lin1, lin2 = model.glob[1], model.glob[3]
        self.glob = (lin1.weight.detach(), lin1.bias.detach(), lin2.weight.detach(), lin2.bias.detach())
        self.pool_size = model.pool.output_size

    def __call__(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        f = x
        for weight, bias, stride, padding in self.convs:
            f = F.conv2d(f, weight, bias, stride, padding).relu_()
        return head_outputs(f, self._columns, self._pooled)

    def _columns(self, flat: torch.Tensor) -> torch.Tensor:
        weight, bias = self.columns
        return torch.matmul(weight, flat).add_(bias)

    def _pooled(self, f: torch.Tensor) -> torch.Tensor:
        """The adaptive average pool as a plain one (f's size is a multiple of the pooled size), then the MLP."""
        w1, b1, w2, b2 = self.glob
        kernel = (f.shape[2] // self.pool_size[0], f.shape[3] // self.pool_size[1])
        return F.linear(F.linear(F.avg_pool2d(f, kernel).flatten(1), w1, b1).relu_(), w2, b2)


def read_checkpoint(path: str | Path) -> dict:
    """The contents of a LaneNet checkpoint (tensors and plain values only: nothing else is unpickled); a file
    that cannot be read as one is a UserError naming it."""
    try:
        ckpt = torch.load(Path(path), map_location="cpu", weights_only=True)
    except OSError as exc:
        raise UserError(f"cannot read checkpoint {path}: {exc.strerror or exc}") from None
    except (RuntimeError, EOFError, ValueError, pickle.UnpicklingError):
        raise UserError(f"cannot read checkpoint {path}: not a torch file of tensors and plain values; use a "
                        f"checkpoint `ld3 ld train` wrote") from None
    if not isinstance(ckpt, dict) or "state_dict" not in ckpt or "width" not in ckpt:
        raise UserError(f"{path} is not a LaneNet checkpoint (no state_dict and width): use one `ld3 ld train` wrote")
    return ckpt


def load_model(path: str | Path | None = None) -> LaneNet:
    """LaneNet from a checkpoint (default: the shipped weights inside the package), in eval mode."""
    if path is None:
        ref = resources.files("testbed.perception.detectors") / "weights" / DEFAULT_WEIGHTS
        with resources.as_file(ref) as p:
            ckpt = read_checkpoint(p)
    else:
        ckpt = read_checkpoint(path)
    return model_from_checkpoint(ckpt, path or DEFAULT_WEIGHTS)


def model_from_checkpoint(ckpt: dict, path: str | Path) -> LaneNet:
    """The LaneNet a read checkpoint describes, in eval mode; a UserError naming `path` when its width is out of
    range or its tensors do not fit that network."""
    width, rows = ckpt["width"], ckpt.get("input_rows", INPUT_ROWS[0])  # older checkpoints: 56 rows
    if not (isinstance(width, int) and 1 <= width <= MAX_WIDTH and rows in INPUT_ROWS):
        raise UserError(f"{path}: a LaneNet checkpoint's width is an integer 1 to {MAX_WIDTH} and "
                        f"its input_rows one of {INPUT_ROWS}, got width {width!r}, input_rows {rows!r}")
    model = LaneNet(width, rows)
    try:
        model.load_state_dict(ckpt["state_dict"])
    except (RuntimeError, TypeError, AttributeError) as exc:  # missing or unexpected keys, shapes that differ
        problem = " ".join(str(exc).split())[:300]
        raise UserError(f"{path}: the weights do not fit a LaneNet of width {width}: "
                        f"{problem}") from None
    return model.eval()


class NeuralLaneDetector(LaneDetector):
    """Runs LaneNet (as `FrozenLaneNet`) on a frame and fits its anchors with `fit` (one of `FITS`); a line under
    0.5 existence probability or with fewer than `MIN_PRESENT_ANCHORS` present anchors is None."""

    def __init__(self, model: LaneNet | None = None, threads: int | None = None, fit: str = DEFAULT_FIT) -> None:
        if threads is not None:
            torch.set_num_threads(threads)
        model = model if model is not None else load_model()
        self.input_rows = model.input_rows
        self.model = FrozenLaneNet(model)
        self.fit = check_fit(fit)

    @staticmethod
    def valid_image(image: np.ndarray | None) -> bool:
        if not isinstance(image, np.ndarray) or image.shape != (*FRAME_SHAPE, 3):
            return False
        return image.dtype == np.uint8 or bool(np.isfinite(image).all())

    def infer(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cubics (2, 4) and existence probabilities (2,) for one valid frame."""
        if image.dtype != np.uint8:
            image = np.clip(image, 0, 255).astype(np.uint8)
        x = torch.from_numpy(preprocess(image, self.input_rows))[None]
        with torch.inference_mode():
            coeffs, probs = lines_from_outputs(*self.model(x), self.fit)
        return coeffs[0], probs[0]

    @staticmethod
    def detection(t: float, coeffs: np.ndarray, probs: np.ndarray) -> LaneDetection:
        """The `LaneDetection` of one frame's cubics (2, 4) and probabilities (2,): a line under 0.5 is None."""
        left, right = (coeffs[i] if probs[i] >= 0.5 else None for i in range(2))
        return LaneDetection(t, left, right, float(probs[0]), float(probs[1]), (0.0, X_ANCHORS[-1]))

    def detect(self, frame: CameraFrame) -> LaneDetection:
        if not self.valid_image(frame.image):
            return LaneDetection.empty(frame.t)
        return self.detection(frame.t, *self.infer(frame.image))
