"""Existence that means lines: the two existence outputs of a LaneNet (rows of its pooled head's last linear layer)
refitted on the frozen network's hidden features, with simulation frames as positives (their existence labels)
and frames without lane lines as negatives (both lines absent). Everything else in the network is unchanged, so
lines, anchors and presence decode exactly as before; only the existence probabilities move.

Negatives (`negative_frames`, all drawn from one seeded stream): uniform and Gaussian noise, dark night frames with
sensor noise, motion-blurred noise, and smooth random textures. The refit is a logistic regression (L-BFGS, one
thread) with an L2 pull toward the original rows; the two sets weigh equally whatever their sizes.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import torch
from torch import nn

from testbed.perception.detectors.neural import FRAME_SHAPE, X_ANCHORS, LaneNet, load_model, preprocess, read_checkpoint
from testbed.perception.training.dataset import iter_shards

NEGATIVE_KINDS = ("uniform", "gaussian", "dark", "motion-blur", "texture")
PULL = 1e-3  # weight of the L2 pull of the refitted rows toward the originals
NEGATIVE_WEIGHT = 0.3  # weight of the negatives' mean loss against the positives' (docs/decisions.md)


def negative_frames(n: int, seed: int) -> list[np.ndarray]:
    """`n` frames (FRAME_SHAPE, RGB uint8) without lane lines, the kinds of `NEGATIVE_KINDS` in turn."""
    rng = np.random.default_rng(seed)
    h, w = FRAME_SHAPE
    frames = []
    for k in range(n):
        kind = NEGATIVE_KINDS[k % len(NEGATIVE_KINDS)]
        if kind == "uniform":
            image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        elif kind == "gaussian":
            image = np.clip(rng.normal(rng.uniform(40, 200), rng.uniform(8, 70), (h, w, 3)), 0, 255).astype(np.uint8)
        elif kind == "dark":
            image = np.clip(rng.normal(rng.uniform(0, 15), rng.uniform(0.5, 5), (h, w, 3)), 0, 255).astype(np.uint8)
        elif kind == "motion-blur":
            length = int(rng.integers(7, 41))
            kernel = np.zeros((length, length), np.float32)
            kernel[length // 2] = 1.0 / length
            rot = cv2.getRotationMatrix2D(((length - 1) / 2, (length - 1) / 2), float(rng.uniform(0, 180)), 1.0)
            kernel = cv2.warpAffine(kernel, rot, (length, length))
            image = cv2.filter2D(rng.integers(0, 256, (h, w, 3), dtype=np.uint8), -1, kernel / max(kernel.sum(), 1e-6))
        else:
            cells = (int(rng.integers(2, 40)), int(rng.integers(2, 20)))
            small = rng.integers(0, 256, (cells[1], cells[0], 3), dtype=np.uint8)
            image = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
        frames.append(np.ascontiguousarray(image))
    return frames


def hidden_features(model: LaneNet, frames: list[np.ndarray] | np.ndarray, batch: int = 256) -> torch.Tensor:
    """The pooled head's hidden layer (N, 64) for frames (N, H, W, 3): what the existence rows read."""
    out = []
    with torch.inference_mode():
        for start in range(0, len(frames), batch):
            x = torch.from_numpy(np.stack([preprocess(f, model.input_rows) for f in frames[start : start + batch]]))
            g = model.glob
            out.append(g[2](g[1](g[0](model.pool(model.features(x))))))
    return torch.cat(out)


def _existence_rows(model: LaneNet) -> slice:
    return slice(2 * len(X_ANCHORS), 2 * len(X_ANCHORS) + 2)


def refit_existence(model: LaneNet, positives: torch.Tensor, labels: torch.Tensor, negatives: torch.Tensor,
                    negative_weight: float = NEGATIVE_WEIGHT) -> tuple[torch.Tensor, torch.Tensor]:
    """New existence rows (2, 64) and biases (2,) from hidden features of positives (labels (N, 2) in {0, 1})
    and negatives (all 0)."""
    last = model.glob[3]
    rows = _existence_rows(model)
    w0, b0 = last.weight.detach()[rows].clone(), last.bias.detach()[rows].clone()
    w, b = nn.Parameter(w0.clone()), nn.Parameter(b0.clone())
    opt = torch.optim.LBFGS([w, b], max_iter=300, line_search_fn="strong_wolfe")
    bce = nn.functional.binary_cross_entropy_with_logits

    def closure() -> torch.Tensor:
        opt.zero_grad()
        loss = bce(positives @ w.T + b, labels)
        loss = loss + negative_weight * bce(negatives @ w.T + b, torch.zeros(len(negatives), 2))
        loss = loss + PULL * ((w - w0).square().sum() + (b - b0).square().sum())
        loss.backward()
        return loss

    opt.step(closure)
    return w.detach(), b.detach()


def positive_set(directories: list[Path], model: LaneNet, limit: int | None = None) -> tuple[torch.Tensor,
                                                                                              torch.Tensor]:
    """Hidden features and existence labels (N, 2) of the frames of simulation datasets."""
    feats, labels = [], []
    for d in directories:
        for shard in iter_shards(d, limit):
            feats.append(hidden_features(model, shard.images))
            labels.append(torch.from_numpy(np.stack([shard.left_exists, shard.right_exists], 1).astype(np.float32)))
    return torch.cat(feats), torch.cat(labels)


def write_refit(init: Path | None, data: list[Path], out: Path, negatives: int, seed: int) -> dict:
    """Refit the existence rows of the checkpoint `init` (None: the default weights) and write the checkpoint to
    `out`; returns the figures on the training frames (the share of each set the refit gets right)."""
    torch.set_num_threads(1)
    model = load_model(init)
    pos, labels = positive_set(data, model)
    neg = hidden_features(model, negative_frames(negatives, seed))
    w, b = refit_existence(model, pos, labels, neg)
    state = {k: v.clone() for k, v in model.state_dict().items()}
    rows = _existence_rows(model)
    state["glob.3.weight"][rows], state["glob.3.bias"][rows] = w, b
    base = read_checkpoint(init) if init is not None else {"width": model.width, "input_rows": model.input_rows}
    history = {"existence_refit_of": str(init or "default weights"), "data": [str(d) for d in data],
               "negatives": negatives, "seed": seed}
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({**base, "state_dict": state, "history": json.dumps(history)}, out)
    with torch.no_grad():
        pos_ok = float((((pos @ w.T + b) > 0) == (labels > 0.5)).float().mean())
        neg_ok = float(((neg @ w.T + b) < 0).all(dim=1).float().mean())
    return {"positives": len(pos), "positive_accuracy": pos_ok, "negatives": len(neg), "negatives_rejected": neg_ok}
