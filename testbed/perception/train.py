"""Training of LaneNet from scratch on CPU, from dataset shards (`ld3 ld dataset`).

Targets are the true lines' offsets y(x) at the anchor distances (masked where a line is not painted)
and the two existence flags. Loss = anchor-weighted smooth-L1 on y / Y_SCALE + binary cross-entropy on
existence. Every batch is mirrored left-right with probability 1/2 (the image flips, left and right lines
swap and negate), AdamW with a one-cycle schedule. Writes the checkpoint and a training-curve PNG.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from testbed.perception.dataset import FrameSet, load_frames
from testbed.perception.neural import ANCHOR_WEIGHTS, X_ANCHORS, Y_SCALE, LaneNet, decode, preprocess


@dataclass
class TrainConfig:
    epochs: int = 30
    batch: int = 64
    lr: float = 3e-3
    weight_decay: float = 1e-4
    threads: int = 2
    seed: int = 0
    max_minutes: float = 28.0


@dataclass
class Tensors:
    """Preprocessed inputs (N, 3, 56, 160) float16; targets anchor y (N, 2, K) / Y_SCALE and exists (N, 2)."""

    x: torch.Tensor
    y: torch.Tensor
    exists: torch.Tensor


def to_tensors(frames: FrameSet) -> Tensors:
    x = np.stack([preprocess(img) for img in frames.images]).astype(np.float16)
    anchors = np.asarray(X_ANCHORS)
    y = np.stack([np.polynomial.polynomial.polyval(anchors, frames.left.T),
                  np.polynomial.polynomial.polyval(anchors, frames.right.T)], axis=1) / Y_SCALE
    exists = np.stack([frames.left_exists, frames.right_exists], axis=1).astype(np.float32)
    return Tensors(torch.from_numpy(x), torch.from_numpy(y.astype(np.float32)), torch.from_numpy(exists))


def mirror(x: torch.Tensor, y: torch.Tensor, exists: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Left-right mirror: flip the image columns, swap left/right lines and negate their offsets."""
    return x.flip(-1), -y.flip(1), exists.flip(1)


def loss_fn(out: torch.Tensor, y: torch.Tensor, exists: torch.Tensor) -> torch.Tensor:
    k = len(X_ANCHORS)
    pred = out[:, : 2 * k].reshape(-1, 2, k)
    w = torch.tensor(ANCHOR_WEIGHTS) / sum(ANCHOR_WEIGHTS) * k
    reg = nn.functional.smooth_l1_loss(pred, y, reduction="none", beta=0.02) * w
    reg = (reg * exists[..., None]).sum() / (exists.sum() * k).clamp(min=1.0)
    cls = nn.functional.binary_cross_entropy_with_logits(out[:, 2 * k :], exists)
    return 20.0 * reg + cls


def dev_error(model: LaneNet, data: Tensors, lane_width: np.ndarray,
              deviation: np.ndarray) -> dict[str, float]:
    """Alg. 3 on the network output (nearer valid line, map lane width) against the true deviation."""
    model.eval()
    outs = []
    with torch.inference_mode():
        for i in range(0, len(data.x), 256):
            outs.append(model(data.x[i : i + 256].float()).numpy())
    out = np.concatenate(outs)
    errs, correct = [], 0
    exists = data.exists.numpy() > 0.5
    for o, lw, d, ex in zip(out, lane_width, deviation, exists, strict=True):
        dec = decode(o.astype(np.float64))
        correct += int(((dec.probs >= 0.5) == ex).sum())
        ok = dec.probs >= 0.5
        dist = np.where(ok, np.abs(dec.anchors_y[:, 0]), np.inf)
        if np.isfinite(dist).any():
            d_ld = lw / 2 - dist[0] if dist[0] <= dist[1] else dist[1] - lw / 2
            errs.append(abs(d_ld - d))
    errs_a = np.asarray(errs) if errs else np.asarray([np.nan])
    return {"mean_abs_dev_err": float(errs_a.mean()), "p99_dev_err": float(np.percentile(errs_a, 99)),
            "existence_acc": correct / (2 * len(out))}


@dataclass
class TrainResult:
    checkpoint: Path
    curve: Path
    history: list[dict] = field(default_factory=list)


def train(train_dirs: list[Path], out: Path, config: TrainConfig | None = None, val_dir: Path | None = None,
          limit: int | None = None, progress: bool = False) -> TrainResult:
    from tqdm import tqdm

    config = config if config is not None else TrainConfig()
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    frames = [load_frames(d, limit) for d in train_dirs]
    parts = [to_tensors(f) for f in frames]
    data = Tensors(*(torch.cat([getattr(p, k) for p in parts]) for k in ("x", "y", "exists")))
    val = load_frames(val_dir) if val_dir is not None else None
    val_t = to_tensors(val) if val is not None else None
    model = LaneNet()
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    n = len(data.x)
    steps_per_epoch = max(1, n // config.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, config.lr, total_steps=config.epochs * steps_per_epoch,
                                                pct_start=0.15)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    history: list[dict] = []
    start = time.monotonic()
    bar = tqdm(total=config.epochs * steps_per_epoch, desc="training", unit="step", disable=not progress)
    for epoch in range(config.epochs):
        model.train()
        order = rng.permutation(n)
        total = 0.0
        for b in range(steps_per_epoch):
            idx = torch.from_numpy(order[b * config.batch : (b + 1) * config.batch])
            x, y, ex = data.x[idx].float(), data.y[idx], data.exists[idx]
            if rng.random() < 0.5:
                x, y, ex = mirror(x, y, ex)
            loss = loss_fn(model(x), y, ex)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += loss.item()
            bar.update(1)
            bar.set_postfix(epoch=epoch, loss=f"{loss.item():.4f}")
        minutes = (time.monotonic() - start) / 60
        row = {"epoch": epoch, "train_loss": total / steps_per_epoch, "minutes": minutes}
        if val is not None and val_t is not None:
            row.update(dev_error(model, val_t, val.lane_width, val.deviation))
        history.append(row)
        save_checkpoint(model, out / "lanenet.pt", history)
        if row["minutes"] > config.max_minutes:
            break
    bar.close()
    curve = plot_curve(history, out / "training_curve.png")
    (out / "history.json").write_text(json.dumps(history, indent=1))
    return TrainResult(out / "lanenet.pt", curve, history)


def save_checkpoint(model: LaneNet, path: Path, history: list[dict]) -> None:
    state = {k: v.detach().clone() for k, v in model.state_dict().items()}
    torch.save({"state_dict": state, "widths": list(model.widths), "hidden": model.hidden,
                "history": json.dumps(history)}, path)


def plot_curve(history: list[dict], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
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
    plt.close(fig)
    return path
