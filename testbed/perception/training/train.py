"""Training of LaneNet from scratch on CPU, from dataset shards (`ld3 ld dataset`).

Targets come from the labels: each line's offset y (m) at every anchor row where the line lies (the dataset's
anchor labels; the label cubic's value in datasets written before them), its column cell there (absent where
the line is unpainted, out of the image or does not reach that far), its c0 and its existence. Loss = column
cross-entropy + L1 on the decoded offsets + L1 on the fitted c0 + weighted existence BCE. Each batch is
mirrored left-right with probability 1/2 (image flipped, lines swapped and negated). Frames without lane lines
(`negatives`, `existence_head.negative_frames`) may be added: both lines absent, every anchor absent. A fine-tune
may keep the batch-norm statistics of its start (`freeze_bn`). The model trains in
channels-last memory format (faster convolutions on CPU); checkpoints hold plain contiguous tensors. AdamW, warm-up then
cosine decay over whichever runs out first, the epochs or the time budget (`max_minutes`, wall clock after
loading). Writes the checkpoint and a training-curve PNG.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from testbed.perception.detectors.neural import (
    ANCHOR_WEIGHTS,
    GEOMETRY,
    INPUT_ROWS,
    N_COLS,
    X_ANCHORS,
    LaneNet,
    NeuralLaneDetector,
    decode,
    fit_cubics,
    lines_from_outputs,
    load_model,
    preprocess,
)
from testbed.perception.training.dataset import FrameSet, iter_shards, load_frames
from testbed.perception.training.evaluate import deviation_errors

EXISTENCE_WEIGHT = 2.0  # weight of the existence BCE in the loss


@dataclass
class TrainConfig:
    epochs: int = 30
    batch: int = 64
    lr: float = 3e-3
    weight_decay: float = 1e-4
    threads: int = 2
    seed: int = 0
    max_minutes: float = 27.0
    input_rows: int = INPUT_ROWS[0]  # network input rows (`neural.INPUT_ROWS`)
    negatives: int = 0  # frames without lane lines added to the training set (drawn with `seed`)
    freeze_bn: bool = False  # keep the batch-norm running statistics of the start


@dataclass
class Tensors:
    """Inputs (N, 3, input rows, 160) float16; targets: anchor offsets y (N, 2, K) m, column class (N, 2, K)
    (N_COLS = absent), offset c0 (N, 2) m and existence (N, 2)."""

    x: torch.Tensor
    y: torch.Tensor
    cls: torch.Tensor
    c0: torch.Tensor
    exists: torch.Tensor

    def take(self, idx: torch.Tensor) -> Tensors:
        return Tensors(self.x[idx].float(), self.y[idx], self.cls[idx], self.c0[idx], self.exists[idx])

    @staticmethod
    def cat(parts: list[Tensors]) -> Tensors:
        return Tensors(*(torch.cat([getattr(p, k) for p in parts]) for k in ("x", "y", "cls", "c0", "exists")))


def load_tensors(directories: list[Path], limit: int | None = None, rows: int = INPUT_ROWS[0]) -> Tensors:
    """Training tensors of the datasets in `directories` (at most `limit` frames each, inputs of `rows` rows),
    converted shard by shard so the raw frames never sit in memory all at once."""
    return Tensors.cat([to_tensors(shard, rows) for d in directories for shard in iter_shards(d, limit)])


def to_tensors(frames: FrameSet, rows: int = INPUT_ROWS[0]) -> Tensors:
    x = np.stack([preprocess(img, rows) for img in frames.images]).astype(np.float16)
    coeffs = np.stack([frames.left, frames.right], axis=1)  # (N, 2, 4)
    y = anchor_offsets(frames, coeffs)
    exists = np.stack([frames.left_exists, frames.right_exists], axis=1)
    u = GEOMETRY.y_to_u(y)
    visible = np.isfinite(u) & (u >= -0.5) & (u < 8.0 * N_COLS - 0.5) & exists[..., None]
    cls = np.full(u.shape, N_COLS, dtype=np.int64)
    cls[visible] = np.floor((u[visible] + 0.5) / 8.0)  # cell j holds pixel centres 8j .. 8j + 7
    y = np.where(np.isfinite(y), y, 0.0)  # an anchor past the line is absent; its offset is never scored
    return Tensors(torch.from_numpy(x), torch.from_numpy(y.astype(np.float32)), torch.from_numpy(cls),
                   torch.from_numpy(coeffs[..., 0].astype(np.float32)),
                   torch.from_numpy(exists.astype(np.float32)))


def anchor_offsets(frames: FrameSet, coeffs: np.ndarray) -> np.ndarray:
    """Each line's offset (N, 2, K) at the anchors: where the line lies (the dataset's anchor labels, NaN past the
    line), or the label cubic's value for datasets written without them."""
    if frames.left_anchors is not None and frames.right_anchors is not None:
        return np.stack([frames.left_anchors, frames.right_anchors], axis=1).astype(float)
    anchors = np.asarray(X_ANCHORS)
    return np.polynomial.polynomial.polyval(anchors, coeffs.reshape(-1, 4).T).reshape(len(coeffs), 2, -1)


def negative_tensors(n: int, seed: int, rows: int = INPUT_ROWS[0]) -> Tensors:
    """`n` frames without lane lines (`existence_head.negative_frames`) as training tensors: both lines absent,
    every anchor's column class absent."""
    from testbed.perception.training.existence_head import negative_frames

    x = np.stack([preprocess(img, rows) for img in negative_frames(n, seed)]).astype(np.float16)
    k = len(X_ANCHORS)
    return Tensors(torch.from_numpy(x), torch.zeros(n, 2, k), torch.full((n, 2, k), N_COLS, dtype=torch.int64),
                   torch.zeros(n, 2), torch.zeros(n, 2))


def mirror(b: Tensors) -> Tensors:
    """Left-right mirror: flip the image columns, swap left/right lines, negate offsets, mirror column cells."""
    cls = b.cls.flip(1)
    cls = torch.where(cls == N_COLS, cls, N_COLS - 1 - cls)
    return Tensors(b.x.flip(-1), -b.y.flip(1), cls, -b.c0.flip(1), b.exists.flip(1))


def loss_fn(cols: torch.Tensor, exist_logits: torch.Tensor, b: Tensors) -> torch.Tensor:
    """Column cross-entropy + L1 on decoded offsets and on the fitted c0 (m, fit in float64) + existence BCE."""
    ce = nn.functional.cross_entropy(cols.reshape(-1, N_COLS + 1), b.cls.reshape(-1))
    y, _ = decode(cols)
    present = (b.cls < N_COLS).float()
    w = torch.tensor(ANCHOR_WEIGHTS)
    l1 = ((y - b.y).abs() * present * w).sum() / (present * w).sum().clamp(min=1.0)
    fitted = fit_cubics(y.double(), present.double())[..., 0].float()
    usable = b.exists * (present.sum(-1) >= 3).float()
    c0 = ((fitted - b.c0).abs() * usable).sum() / usable.sum().clamp(min=1.0)
    bce = nn.functional.binary_cross_entropy_with_logits(exist_logits, b.exists)
    return ce + 5.0 * l1 + 5.0 * c0 + EXISTENCE_WEIGHT * bce


def dev_error(model: LaneNet, data: Tensors, lane_width: np.ndarray,
              deviation: np.ndarray) -> dict[str, float]:
    """Alg. 3 on the detector's output against the true deviation (`evaluate.deviation_errors`), per frame."""
    model.eval()
    outputs = []
    with torch.inference_mode():
        for i in range(0, len(data.x), 256):
            outputs.append(lines_from_outputs(*model(data.x[i : i + 256].float())))
    coeffs, probs = (np.concatenate(part) for part in zip(*outputs, strict=True))
    detections = [NeuralLaneDetector.detection(0.0, c, p) for c, p in zip(coeffs, probs, strict=True)]
    errs = deviation_errors(detections, lane_width, deviation, 0.5)
    errs_arr = errs[np.isfinite(errs)] if np.isfinite(errs).any() else np.asarray([np.nan])
    acc = float(((probs >= 0.5) == (data.exists.numpy() > 0.5)).mean())
    return {"mean_abs_dev_err": float(errs_arr.mean()), "p99_dev_err": float(np.percentile(errs_arr, 99)),
            "existence_acc": acc}


def lr_at(peak: float, done: float) -> float:
    """Linear warm-up over the first 5 % of training, then cosine decay to 1 % of `peak` at done = 1."""
    if done < 0.05:
        return peak * (0.1 + 0.9 * done / 0.05)
    return peak * (0.01 + 0.99 * 0.5 * (1.0 + math.cos(math.pi * min(1.0, (done - 0.05) / 0.95))))


@dataclass
class TrainResult:
    checkpoint: Path
    curve: Path
    history: list[dict] = field(default_factory=list)


def train(train_dirs: list[Path], out: Path, config: TrainConfig | None = None, val_dir: Path | None = None,
          limit: int | None = None, progress: bool = False, init: Path | None = None) -> TrainResult:
    """Train (from scratch, or on from the checkpoint `init`) and write checkpoint, history and curve to `out`."""
    from tqdm import tqdm

    config = config if config is not None else TrainConfig()
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    model = load_model(init).train() if init is not None else LaneNet(input_rows=config.input_rows)
    if model.input_rows != config.input_rows:
        raise ValueError(f"the checkpoint {init} takes {model.input_rows}-row inputs, the config asks for "
                         f"{config.input_rows}: train on with input_rows={model.input_rows} or start from scratch")
    data = load_tensors(train_dirs, limit, config.input_rows)
    if config.negatives:
        data = Tensors.cat([data, negative_tensors(config.negatives, config.seed, config.input_rows)])
    val = load_frames(val_dir) if val_dir is not None else None
    val_t = to_tensors(val, config.input_rows) if val is not None else None
    model = model.to(memory_format=torch.channels_last)  # NHWC convolutions: faster training steps on CPU
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    n = len(data.x)
    steps_per_epoch = max(1, n // config.batch)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    history: list[dict] = []
    start = time.monotonic()
    bar = tqdm(total=config.epochs * steps_per_epoch, desc="training", unit="step", disable=not progress)
    for epoch in range(config.epochs):
        model.train()
        if config.freeze_bn:
            for module in model.modules():
                if isinstance(module, nn.BatchNorm2d):
                    module.eval()
        order = rng.permutation(n)
        total, steps = 0.0, 0
        for b in range(steps_per_epoch):
            idx = torch.from_numpy(order[b * config.batch : (b + 1) * config.batch])
            done = max((epoch * steps_per_epoch + b) / (config.epochs * steps_per_epoch),
                       (time.monotonic() - start) / 60.0 / config.max_minutes)
            if done >= 1.0:
                break
            for group in opt.param_groups:
                group["lr"] = lr_at(config.lr, done)
            batch = data.take(idx)
            if rng.random() < 0.5:
                batch = mirror(batch)
            loss = loss_fn(*model(batch.x.contiguous(memory_format=torch.channels_last)), batch)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item()
            steps += 1
            bar.update(1)
            bar.set_postfix(epoch=epoch, loss=f"{loss.item():.4f}")
        minutes = (time.monotonic() - start) / 60
        row = {"epoch": epoch, "train_loss": total / max(1, steps), "minutes": minutes}
        if val is not None and val_t is not None:
            row.update(dev_error(model, val_t, val.lane_width, val.deviation))
        history.append(row)
        save_checkpoint(model, out / "lanenet.pt", history)
        if done >= 1.0:
            break
    bar.close()
    curve = plot_curve(history, out / "training_curve.png")
    (out / "history.json").write_text(json.dumps(history, indent=1))
    return TrainResult(out / "lanenet.pt", curve, history)


def save_checkpoint(model: LaneNet, path: Path, history: list[dict]) -> None:
    state = {k: v.detach().contiguous().clone() for k, v in model.state_dict().items()}  # NCHW on disk
    torch.save({"state_dict": state, "width": model.width, "input_rows": model.input_rows,
                "history": json.dumps(history)}, path)


def plot_curve(history: list[dict], path: Path) -> Path:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.5))
    ax = fig.subplots()
    epochs = [h["epoch"] for h in history]
    ax.plot(epochs, [h["train_loss"] for h in history], label="train loss")
    ax.set_yscale("log")
    ax.set_xlabel("epoch")
    if history and "mean_abs_dev_err" in history[0]:
        ax.plot(epochs, [h["mean_abs_dev_err"] for h in history], label="held-out mean |D_LD err| (m)")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path
